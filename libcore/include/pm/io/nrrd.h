#pragma once
// NRRD (.nrrd attached, .nhdr detached; raw or gzip) through Teem.
//
// Reading: exactly 3 axes of a scalar type (block types are rejected). The
// header is read first without data; sizes are checked against the bytes the
// (single) data file holds before Teem allocates anything. Geometry comes from
// "space origin" + "space directions" when the file has a space, converted
// from the named space into libcore's LPS (pm/base/volume.h):
// right-anterior-superior negates x and y, left-anterior-superior y;
// left-posterior-superior and scanner-xyz (DICOM's patient frame) are LPS;
// 3D-right-handed, 3D-left-handed and a bare "space dimension: 3" have no
// anatomy and are kept as given; the "-time" spaces need a time component of
// 0 in every axis direction. A 2-D space, or a space whose dimension differs
// from the space directions', is an error. Without a space: "spacings" (1
// when absent; or from axis mins/maxs) with "axis mins" as the origin, kept as
// given. Voxels are node samples: for an axis with "centers: cell" and an
// axis min, the first sample sits half a spacing inside the min. Teem's own
// complaints are passed on as its innermost reason.
// Writing: "space: left-posterior-superior", space directions, space origin,
// kinds domain; raw or gzip encoding, native byte order.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (see read_volume).
Volume read_nrrd(const std::string& path);
/// Writes `path` directly (callers use write_volume for atomicity). For .nhdr
/// the data file is written beside it.
void write_nrrd(const Volume& v, const std::string& path, bool gzip = true);
/// Detached NRRD pair: the header goes to `header_path` and names `data_name`
/// (a file name relative to the header's folder) in its "data file" field;
/// the voxels go to `data_path`, which must be in the same folder. write_volume
/// writes both under temporary names this way, the header already naming the
/// final data file, then renames them into place.
void write_nrrd_detached(const Volume& v, const std::string& header_path, const std::string& data_path,
                         const std::string& data_name, bool gzip = true);
/// The data file write_nrrd puts beside a .nhdr: "<dir>/<stem>.raw.gz" (gzip)
/// or "<dir>/<stem>.raw".
std::string nhdr_data_path(const std::string& header_path, bool gzip);
}  // namespace pm

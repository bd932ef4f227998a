#pragma once
// NRRD (.nrrd attached, .nhdr detached; raw or gzip) through Teem.
//
// Reading: exactly 3 axes of a scalar type (block types are rejected). The
// header is read first without data; sizes are checked against the bytes the
// (single) data file holds before Teem allocates anything. Geometry comes from
// "space origin" + "space directions" when the file has a space (its world
// coordinates are kept as they are, whatever the named space, e.g. LPS or
// RAS), else from "spacings" (1 when absent; or from axis mins/maxs) with
// "axis mins" as the origin. Voxels are node samples: for an axis with
// "centers: cell" and an axis min, the first sample sits half a spacing inside
// the min. Teem's own complaints are passed on as its innermost reason.
// Writing: "space dimension: 3" (no named space), space directions, space
// origin, kinds domain; raw or gzip encoding, native byte order.
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

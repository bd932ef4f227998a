#pragma once
// Read and write volumes, choosing the format by file extension:
//   .nrrd .nhdr (Teem; raw or gzip)   read + write
//   .vdb (OpenVDB float / int grids)   read + write
//   .mha .mhd (MetaImage, raw/zraw)    read + write
//   .nii .nii.gz (NIfTI-1)             read + write
//   .inr .inr.gz (INRimage)            read + write
// Geometry (origin, spacing, directions) survives every round trip the
// format can represent, in libcore's LPS world frame (pm/base/volume.h):
// each reader converts the file's frame into LPS and each writer converts
// out of it, so the same voxel maps to the same anatomical point in every
// format; Volume::frame_source() says what the file's frame was.
#include <cstdint>
#include <string>

#include "pm/base/volume.h"

namespace pm {

/// Options for writing.
struct VolumeWriteParams {
  bool compress = true;  ///< gzip where the format allows (NRRD, MHA zraw, NIfTI .gz by name)
};

/// \throw IoError (missing/unreadable file), InputError (bad header, not 3-D,
/// unknown voxel type, zero-size axis, truncated data). Messages start with
/// the function and quoted file name: `read_volume: "x.nrrd": expected 3 axes, got 2`.
Volume read_volume(const std::string& path);

/// Writes atomically (temporary file + rename). \throw IoError, InputError
/// (type not representable by the format).
void write_volume(const Volume& v, const std::string& path, const VolumeWriteParams& p = {});

/// True if the extension is one read_volume knows.
bool is_volume_path(const std::string& path);
/// The extensions read_volume knows, for messages: ".nrrd .nhdr .vdb ...".
std::string volume_extensions();

}  // namespace pm

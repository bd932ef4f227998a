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

// --- helpers shared by the format readers ------------------------------------

/// Most voxels a header may claim (2^34); larger counts are taken as corrupt.
constexpr std::uint64_t kMaxVolumeVoxels = std::uint64_t(1) << 34;

/// Validate what a header says before any voxel memory is allocated: every
/// axis has size >= 1, the voxel count is at most kMaxVolumeVoxels, each
/// spacing (length of a direction column) is finite and > 0, the origin is
/// finite and the directions are independent.
/// \throw InputError `who: "path": spacing of axis 2 is 0; expected > 0`.
void check_volume_header(const std::string& who, const std::string& path, const Dims& dims,
                         const Geometry& g);

/// Validate a scalar spacing field (NRRD spacings, MetaImage ElementSpacing,
/// INR VX, NIfTI pixdim): finite and > 0.
/// \throw InputError `who: "path": spacing of axis 1 is -2; expected > 0`.
void check_spacing(const std::string& who, const std::string& path, int axis, double s);

}  // namespace pm

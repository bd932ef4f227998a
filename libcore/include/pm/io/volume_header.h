#pragma once
// Header checks shared by the volume format readers (nrrd, nifti, metaimage,
// inr, vdb) and read_volume: what a header claims is validated before any
// voxel memory is allocated. Below the readers and volume_io.h, so that no
// reader calls back into the dispatch.
#include <cstdint>
#include <string>

#include "pm/base/volume.h"

namespace pm {

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

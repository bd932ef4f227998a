#pragma once
// NIfTI-1 (.nii, .nii.gz) via nifticlib. Geometry from the sform when set,
// else the qform, else pixdim; converted from NIfTI's RAS to our LPS-free
// convention: we keep NIfTI world coordinates as they are (RAS).
#include <string>

#include "pm/base/volume.h"

namespace pm {
Volume read_nifti(const std::string& path);
void write_nifti(const Volume& v, const std::string& path);
}  // namespace pm

#pragma once
// NIfTI-1 (.nii, .nii.gz) via nifticlib. Geometry from the sform when set,
// else the qform, else pixdim; converted from NIfTI's RAS to our LPS-free
// convention: we keep NIfTI world coordinates as they are (RAS), in the
// file's units (xyz_units is not applied).
//
// Reading: 3-D images (dim[0] == 3, or more with every extra axis of size 1,
// e.g. 4-D with nt == 1) of DT_UINT8 .. DT_FLOAT64 scalars. Stored values are
// returned raw: scl_slope / scl_inter are NOT applied, so label maps stay
// integers. Sizes are checked against the file before loading.
// Writing: sform = our geometry exactly (as float32, NIfTI's precision),
// qform = its closest rotation + spacing (shear cannot be represented there),
// both with code NIFTI_XFORM_SCANNER_ANAT; xyz_units unknown. .nii.gz by name.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (not NIfTI-1, not 3-D, type, truncated).
Volume read_nifti(const std::string& path);
/// \throw InputError (an axis longer than 32767), IoError.
void write_nifti(const Volume& v, const std::string& path);
}  // namespace pm

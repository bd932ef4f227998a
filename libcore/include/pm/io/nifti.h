#pragma once
// NIfTI-1 (.nii, .nii.gz) via nifticlib. Geometry from the sform when its
// code is > 0, else the qform when its code is > 0 (as nibabel), converted
// from NIfTI's RAS into libcore's LPS (x and y negated; pm/base/volume.h) and
// from xyzt_units into mm (metres x 1000, micrometres x 0.001; unknown is
// taken as mm). With both codes 0 there is no world frame: index times
// pixdim, origin 0, kept as given, and a warning (pm::warn) says so.
//
// Reading: 3-D images (dim[0] == 3, or more with every extra axis of size 1,
// e.g. 4-D with nt == 1) of DT_UINT8 .. DT_FLOAT64 scalars. Stored values are
// returned raw: scl_slope / scl_inter are NOT applied, so label maps stay
// integers. Sizes are checked against the file before loading.
// Writing: sform = our geometry taken to RAS (as float32, NIfTI's
// precision), qform = its closest rotation + spacing (shear cannot be
// represented there), both with code NIFTI_XFORM_SCANNER_ANAT; xyz_units mm.
// .nii.gz by name.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (not NIfTI-1, not 3-D, type, truncated).
Volume read_nifti(const std::string& path);
/// \throw InputError (an axis longer than 32767), IoError.
void write_nifti(const Volume& v, const std::string& path);
}  // namespace pm

#include "pm/io/nifti.h"

#include <nifti/nifti1_io.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <sstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/io/gzip.h"
#include "pm/io/volume_header.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

const char* const kWho = "read_nifti";

// nifticlib reports problems on stderr unless its debug level is 0; our own
// messages say what went wrong instead.
void quiet_nifticlib() {
  static std::once_flag once;
  std::call_once(once, [] { nifti_set_debug_level(0); });
}

struct NimDeleter {
  void operator()(nifti_image* n) const { nifti_image_free(n); }
};
using NimPtr = std::unique_ptr<nifti_image, NimDeleter>;

bool from_nifti_type(int dt, VoxelType& t) {
  switch (dt) {
    case DT_UINT8: t = VoxelType::u8; return true;
    case DT_INT8: t = VoxelType::i8; return true;
    case DT_UINT16: t = VoxelType::u16; return true;
    case DT_INT16: t = VoxelType::i16; return true;
    case DT_UINT32: t = VoxelType::u32; return true;
    case DT_INT32: t = VoxelType::i32; return true;
    case DT_UINT64: t = VoxelType::u64; return true;
    case DT_INT64: t = VoxelType::i64; return true;
    case DT_FLOAT32: t = VoxelType::f32; return true;
    case DT_FLOAT64: t = VoxelType::f64; return true;
    default: return false;
  }
}

int to_nifti_type(VoxelType t) {
  switch (t) {
    case VoxelType::u8: return DT_UINT8;
    case VoxelType::i8: return DT_INT8;
    case VoxelType::u16: return DT_UINT16;
    case VoxelType::i16: return DT_INT16;
    case VoxelType::u32: return DT_UINT32;
    case VoxelType::i32: return DT_INT32;
    case VoxelType::u64: return DT_UINT64;
    case VoxelType::i64: return DT_INT64;
    case VoxelType::f32: return DT_FLOAT32;
    case VoxelType::f64: return DT_FLOAT64;
  }
  return DT_UNKNOWN;
}

// A NIfTI index-to-world matrix (RAS, in the file's units) as our geometry in
// LPS and mm.
Geometry from_mat44(const mat44& m, double to_mm) {
  Geometry g;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g.directions[r][c] = m.m[r][c] * to_mm;
    g.origin[r] = m.m[r][3] * to_mm;
  }
  return with_world_signs(g, {-1, -1, 1});
}

const char* xform_name(int code) {
  switch (code) {
    case NIFTI_XFORM_SCANNER_ANAT: return "scanner_anat";
    case NIFTI_XFORM_ALIGNED_ANAT: return "aligned_anat";
    case NIFTI_XFORM_TALAIRACH: return "talairach";
    case NIFTI_XFORM_MNI_152: return "mni_152";
    default: return "unknown code";
  }
}

// Look at the raw header before nifticlib does, which would print its own
// complaints on stderr: sizeof_hdr 348 (either byte order) and magic "n+1".
void check_nifti1_header(const std::string& path, const std::string& where) {
  unsigned char h[348];
  GzipReader in(path, where);
  if (in.read(h, sizeof h) != sizeof h)
    throw InputError(where + ": shorter than a NIfTI-1 header (348 bytes); expected a .nii or .nii.gz file");
  std::uint32_t size;
  std::memcpy(&size, h, 4);
  const std::uint32_t swapped = (size >> 24) | ((size >> 8) & 0xff00u) | ((size << 8) & 0xff0000u) | (size << 24);
  if (size == 540 || swapped == 540) throw InputError(where + ": a NIfTI-2 file; expected NIfTI-1");
  if (size != 348 && swapped != 348)
    throw InputError(where + ": not a NIfTI-1 file (sizeof_hdr is not 348); expected a .nii or .nii.gz file");
  if (std::memcmp(h + 344, "n+1", 4) != 0)
    throw InputError(where + ": no \"n+1\" magic (ANALYZE or a .hdr/.img pair?); expected a single-file NIfTI-1");
  // nifticlib silently turns a size <= 0 into 1 (a header saying -2 would be
  // read as 1): refuse such sizes here, in the file's byte order.
  const bool swap = size != 348;
  std::int16_t dim[8];
  for (int i = 0; i < 8; ++i) {
    std::uint16_t u;
    std::memcpy(&u, h + 40 + 2 * i, 2);
    if (swap) u = std::uint16_t((u >> 8) | (u << 8));
    std::memcpy(&dim[i], &u, 2);
  }
  if (dim[0] < 1 || dim[0] > 7) {
    std::ostringstream m;
    m << where << ": dim[0] (the number of axes) is " << dim[0] << "; expected 3 (1..7 with extra axes of size 1)";
    throw InputError(m.str());
  }
  for (int i = 1; i <= dim[0]; ++i) {
    if (dim[i] < (i <= 3 ? 1 : 0)) {  // some writers put 0 for an unused 4th axis
      std::ostringstream m;
      m << where << ": dim[" << i << "] is " << dim[i] << "; expected a size >= 1";
      throw InputError(m.str());
    }
  }
}

}  // namespace

Volume read_nifti(const std::string& path) {
  const std::string where = std::string(kWho) + ": " + quote(path);
  require_readable(path);
  quiet_nifticlib();

  check_nifti1_header(path, where);
  NimPtr nim(nifti_image_read(path.c_str(), 0));
  if (!nim) throw InputError(where + ": not a readable NIfTI-1 header; expected a .nii or .nii.gz file");

  // 3-D, or higher with every extra axis of size 1 (e.g. 4-D with nt = 1).
  const int nd = nim->dim[0];
  int axes = nd;
  while (axes > 3 && nim->dim[axes] == 1) --axes;
  if (nd < 3 || axes != 3) {
    std::ostringstream m;
    m << where << ": expected 3 axes, got " << nd << " (dim =";
    for (int i = 1; i <= std::min(nd, 7); ++i) m << " " << nim->dim[i];
    m << ")";
    throw InputError(m.str());
  }
  VoxelType type;
  if (!from_nifti_type(nim->datatype, type)) {
    const char* name = nifti_datatype_to_string(nim->datatype);
    throw InputError(where + ": datatype " + (name ? name : "?") + " (" + std::to_string(nim->datatype) +
                     ") is not supported; expected a scalar type DT_UINT8 .. DT_FLOAT64");
  }
  for (int a = 1; a <= 3; ++a) {
    if (nim->dim[a] < 0) {
      std::ostringstream m;
      m << where << ": dim[" << a << "] is " << nim->dim[a] << "; expected >= 1";
      throw InputError(m.str());
    }
  }
  const Dims dims{static_cast<std::size_t>(nim->dim[1]), static_cast<std::size_t>(nim->dim[2]),
                  static_cast<std::size_t>(nim->dim[3])};

  // Geometry: sform, else qform (both RAS, taken to LPS), else pixdim (no
  // frame). Units: xyzt_units' space part; unknown (0) is taken as mm, as
  // nibabel and ITK do.
  double to_mm = 1;
  std::string units = "mm";
  switch (nim->xyz_units) {
    case NIFTI_UNITS_METER: to_mm = 1000, units = "m"; break;
    case NIFTI_UNITS_MM: break;
    case NIFTI_UNITS_MICRON: to_mm = 0.001, units = "um"; break;
    case NIFTI_UNITS_UNKNOWN: units = "unknown units, taken as mm"; break;
    default: units = "unknown units code " + std::to_string(nim->xyz_units) + ", taken as mm";
  }
  Geometry g;
  FrameSource frame;
  frame.format = "NIfTI";
  if (nim->sform_code > 0) {
    g = from_mat44(nim->sto_xyz, to_mm);
    frame.space = std::string("RAS (sform, ") + xform_name(nim->sform_code) + ", " + units + ")";
  } else if (nim->qform_code > 0) {
    g = from_mat44(nim->qto_xyz, to_mm);
    frame.space = std::string("RAS (qform, ") + xform_name(nim->qform_code) + ", " + units + ")";
  } else {
    const double sp[3] = {nim->dx, nim->dy, nim->dz};
    for (int a = 0; a < 3; ++a) check_spacing(kWho, path, a, sp[a]);
    g = Geometry::with_spacing(sp[0], sp[1], sp[2]);
    frame.space = "none (qform_code = sform_code = 0)";
    frame.anatomical = false;
    frame.note = "no qform or sform: voxel indices times pixdim, origin 0, not anatomical coordinates";
  }
  check_volume_header(kWho, path, dims, g);

  // Data size against the file before allocating.
  const std::uint64_t need = std::uint64_t(dims.count()) * voxel_size(type);
  std::error_code ec;
  const std::uint64_t bytes = fs::file_size(path, ec);
  if (!ec) {
    const bool gz = file_extension(path) == ".nii.gz";
    const std::uint64_t offset = nim->iname_offset > 0 ? std::uint64_t(nim->iname_offset) : 352;
    const std::uint64_t avail = bytes > offset ? bytes - offset : 0;
    std::ostringstream m;
    if (!gz && avail < need) {
      m << where << ": truncated: expected " << need << " bytes of voxel data (" << dims.nx << "x" << dims.ny << "x"
        << dims.nz << " " << voxel_type_name(type) << ") after the header, the file holds " << avail;
      throw InputError(m.str());
    }
    if (gz && need > max_inflated_size(bytes)) {
      m << where << ": truncated or corrupt: header claims " << need << " bytes of voxel data, " << bytes
        << " gzip bytes can hold at most " << max_inflated_size(bytes);
      throw InputError(m.str());
    }
  }
  if (nifti_image_load(nim.get()) != 0 || !nim->data)
    throw InputError(where + ": cannot read the voxel data (truncated or corrupt?)");
  if (std::uint64_t(nim->nvox) * std::uint64_t(nim->nbyper) < need)
    throw InputError(where + ": nifticlib returned fewer voxels than the header claims");
  // Raw stored values: scl_slope / scl_inter are not applied (labels stay integers).
  Volume v(type, dims, g);
  std::memcpy(v.raw(), nim->data, v.byte_size());
  if (!frame.anatomical)
    warn(std::string(kWho) + ": " + quote(path) + ": qform_code and sform_code are both 0 (no world frame); " +
         "using voxel units: index times pixdim, origin 0, not anatomical coordinates");
  v.set_frame_source(std::move(frame));
  return v;
}

void write_nifti(const Volume& v, const std::string& path) {
  const std::string where = "write_nifti: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  const std::string ext = file_extension(path);
  if (ext != ".nii" && ext != ".nii.gz") throw UsageError(where + ": expected a .nii or .nii.gz file name");
  if (ext == ".nii.gz" && !nifti_compiled_with_zlib())
    throw IoError(where + ": nifticlib was built without zlib; expected .nii");
  quiet_nifticlib();
  const Dims& d = v.dims();
  const std::size_t limit = 32767;  // NIfTI-1 stores sizes as int16
  if (d.nx > limit || d.ny > limit || d.nz > limit) {
    std::ostringstream m;
    m << where << ": size " << d.nx << "x" << d.ny << "x" << d.nz << " does not fit NIfTI-1; expected every axis <= "
      << limit;
    throw InputError(m.str());
  }
  int dims[8] = {3, int(d.nx), int(d.ny), int(d.nz), 1, 1, 1, 1};
  NimPtr nim(nifti_make_new_nim(dims, to_nifti_type(v.type()), 0));
  if (!nim) throw IoError(where + ": nifticlib could not make an image header");

  // sform = our index-to-world map taken from LPS to NIfTI's RAS; qform = its
  // nearest rigid-plus-scale part. Units: mm.
  const Geometry g = with_world_signs(v.geometry(), {-1, -1, 1});
  mat44 m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m.m[r][c] = 0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.m[r][c] = static_cast<float>(g.directions[r][c]);
    m.m[r][3] = static_cast<float>(g.origin[r]);
  }
  m.m[3][3] = 1;
  nim->xyz_units = NIFTI_UNITS_MM;
  nim->sform_code = NIFTI_XFORM_SCANNER_ANAT;
  nim->sto_xyz = m;
  nim->sto_ijk = nifti_mat44_inverse(m);
  float qb, qc, qd, qx, qy, qz, dx, dy, dz, qfac;
  nifti_mat44_to_quatern(m, &qb, &qc, &qd, &qx, &qy, &qz, &dx, &dy, &dz, &qfac);
  nim->qform_code = NIFTI_XFORM_SCANNER_ANAT;
  nim->quatern_b = qb;
  nim->quatern_c = qc;
  nim->quatern_d = qd;
  nim->qoffset_x = qx;
  nim->qoffset_y = qy;
  nim->qoffset_z = qz;
  nim->qfac = qfac;
  nim->dx = nim->pixdim[1] = static_cast<float>(g.spacing(0));
  nim->dy = nim->pixdim[2] = static_cast<float>(g.spacing(1));
  nim->dz = nim->pixdim[3] = static_cast<float>(g.spacing(2));
  nim->pixdim[0] = qfac;
  nim->qto_xyz = nifti_quatern_to_mat44(qb, qc, qd, qx, qy, qz, nim->dx, nim->dy, nim->dz, qfac);
  nim->qto_ijk = nifti_mat44_inverse(nim->qto_xyz);

  if (nifti_set_filenames(nim.get(), path.c_str(), 0, 1) != 0)
    throw IoError(where + ": nifticlib does not accept this file name");
  nim->data = const_cast<void*>(v.raw());
  nifti_image_write(nim.get());
  nim->data = nullptr;  // ours, not nifticlib's to free

  // nifti_image_write returns nothing: check what it left behind.
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || size == 0) throw IoError(where + ": nifticlib could not write the file");
  if (ext == ".nii" && size < 352 + v.byte_size()) {
    std::ostringstream msg;
    msg << where << ": incomplete file: " << size << " bytes; expected " << 352 + v.byte_size();
    throw IoError(msg.str());
  }
}

}  // namespace pm

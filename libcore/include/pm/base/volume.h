#pragma once
// A 3-D scalar grid with world geometry, of any voxel type.
//
// World position of voxel (i,j,k): origin + D * (i,j,k), where D is the 3x3
// matrix whose column a is the world displacement of one step along axis a
// (NRRD "space directions"; its length is the spacing of that axis). Voxels
// are samples at nodes ("cell-centered" data are treated as node samples at
// the cell centres). Axis 0 varies fastest in memory.
//
// World frame: LPS. Every world coordinate inside libcore (volume origins
// and directions, particles, meshes) is patient LPS: +x towards the
// patient's Left, +y Posterior, +z Superior, as in DICOM, ITK, 3D Slicer's
// files and MetaImage. The volume readers convert into it (NRRD
// "space", NIfTI's RAS sform/qform and xyzt_units, MetaImage, which is LPS;
// INR and VDB carry no frame and are taken as LPS) and the writers convert
// out of it (NRRD "space: left-posterior-superior", NIfTI RAS sform + qform
// in mm, MetaImage LPS), so a conversion between any two formats keeps the
// anatomy: the same voxel sits at the same anatomical point. RAS (NIfTI,
// FreeSurfer) is LPS with x and y negated: ras_from_lps(). Files without any
// frame (NRRD without "space", a NIfTI with qform_code = sform_code = 0, a
// volume made from a mesh) keep their coordinates as given. World units are
// millimetres where the file states its units (NIfTI xyzt_units: metres and
// micrometres are converted), otherwise the file's numbers as they are.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pm/base/vec.h"

namespace pm {

enum class VoxelType { u8, i8, u16, i16, u32, i32, u64, i64, f32, f64 };

/// "uint8", "int16", "float", ... (NRRD spelling).
const char* voxel_type_name(VoxelType t);
/// Bytes per voxel.
std::size_t voxel_size(VoxelType t);
bool is_integer(VoxelType t);
/// Parse a name as printed by voxel_type_name (also accepts "u8", "f32", ...).
/// \throw UsageError for an unknown name.
VoxelType parse_voxel_type(const std::string& name);

struct Dims {
  std::size_t nx = 0, ny = 0, nz = 0;
  std::size_t operator[](int a) const { return a == 0 ? nx : (a == 1 ? ny : nz); }
  std::size_t count() const { return nx * ny * nz; }
  bool operator==(const Dims& o) const { return nx == o.nx && ny == o.ny && nz == o.nz; }
};

/// Index-to-world mapping of a grid.
struct Geometry {
  Vec3 origin;                        ///< world position of voxel (0,0,0)
  Mat3 directions = Mat3::identity(); ///< column a: world step along axis a
  /// Spacing of axis a (length of column a), world units.
  double spacing(int a) const { return norm(directions.column(a)); }
  Vec3 index_to_world(const Vec3& ijk) const { return origin + directions * ijk; }
  Vec3 world_to_index(const Vec3& x) const;
  /// True when the directions are axis-aligned (diagonal matrix).
  bool axis_aligned() const;
  static Geometry with_spacing(double sx, double sy, double sz, Vec3 origin = {});
};

/// A point in RAS from one in LPS (x and y negated); its own inverse, so it
/// also maps RAS to LPS.
inline Vec3 ras_from_lps(const Vec3& p) { return {-p.x, -p.y, p.z}; }
inline Vec3 lps_from_ras(const Vec3& p) { return ras_from_lps(p); }
/// g with its world coordinates mapped by S = diag(s.x, s.y, s.z), each +1 or
/// -1: origin' = S * origin, directions' = S * directions (the voxels stay
/// where they are in the anatomy; only the world axes turn).
/// with_world_signs(g, {-1, -1, 1}) maps RAS to LPS and back.
Geometry with_world_signs(const Geometry& g, const Vec3& s);

/// Where a volume's world coordinates came from, as the reader found it
/// (volconv --info reports it). Empty for volumes made in memory.
struct FrameSource {
  std::string format;  ///< "NRRD", "NIfTI", "MetaImage", "INR", "VDB"
  /// The file's own frame as it names it, e.g. "right-anterior-superior"
  /// (NRRD space), "RAS (sform, scanner_anat, mm)", "none".
  std::string space;
  /// One line when the coordinates are not anatomical or were taken without
  /// a frame (INR, a NIfTI without qform and sform), else empty.
  std::string note;
  /// False when the file has no frame and the coordinates are kept as given.
  bool anatomical = true;
};

/// Calls f(T{}) with T the C++ type of voxel type t (std::uint8_t ... double),
/// for typed loops over Volume::data<T>() instead of a get() call per voxel.
template <class F>
decltype(auto) visit_voxel_type(VoxelType t, F&& f) {
  switch (t) {
    case VoxelType::u8: return f(std::uint8_t{});
    case VoxelType::i8: return f(std::int8_t{});
    case VoxelType::u16: return f(std::uint16_t{});
    case VoxelType::i16: return f(std::int16_t{});
    case VoxelType::u32: return f(std::uint32_t{});
    case VoxelType::i32: return f(std::int32_t{});
    case VoxelType::u64: return f(std::uint64_t{});
    case VoxelType::i64: return f(std::int64_t{});
    case VoxelType::f32: return f(float{});
    case VoxelType::f64: return f(double{});
  }
  return f(float{});
}

/// Volume: dims, geometry, and a typed voxel buffer.
class Volume {
 public:
  Volume() = default;
  /// Zero-filled volume. \throw InputError when a dimension is 0 or the
  /// voxel count overflows.
  Volume(VoxelType type, Dims dims, Geometry geometry = {});

  VoxelType type() const { return type_; }
  const Dims& dims() const { return dims_; }
  const Geometry& geometry() const { return geometry_; }
  Geometry& geometry() { return geometry_; }
  /// Set by the volume readers: the frame the file's coordinates were in.
  const FrameSource& frame_source() const { return frame_source_; }
  void set_frame_source(FrameSource f) { frame_source_ = std::move(f); }
  /// Key/value pairs about the voxels (NRRD's `key:=value` lines; the NRRD
  /// reader and writer keep them, other formats drop them), e.g.
  /// kExactPositiveKey. Copies of the volume keep them; derived volumes
  /// (converted(), resampled, ...) start without.
  const std::map<std::string, std::string>& keys() const { return keys_; }
  void set_key(const std::string& key, const std::string& value) { keys_[key] = value; }
  /// The value of `key`, or empty when the volume has none.
  std::string key(const std::string& key) const {
    const auto it = keys_.find(key);
    return it == keys_.end() ? std::string() : it->second;
  }
  std::size_t count() const { return dims_.count(); }
  bool empty() const { return count() == 0; }

  std::size_t index(std::size_t i, std::size_t j, std::size_t k) const {
    return i + dims_.nx * (j + dims_.ny * k);
  }
  /// Voxel value converted to double (exact for all types but 64-bit ints > 2^53).
  double get(std::size_t idx) const;
  double get(std::size_t i, std::size_t j, std::size_t k) const { return get(index(i, j, k)); }
  /// Store v converted to the voxel type (rounded and clamped for integer types).
  void set(std::size_t idx, double v);
  void set(std::size_t i, std::size_t j, std::size_t k, double v) { set(index(i, j, k), v); }

  void* raw() { return bytes_.data(); }
  const void* raw() const { return bytes_.data(); }
  std::size_t byte_size() const { return bytes_.size(); }

  /// Typed access; \throw Error when T does not match type().
  template <class T> T* data();
  template <class T> const T* data() const;

  /// All voxels as float / double (copy).
  std::vector<float> to_float() const;
  std::vector<double> to_double() const;
  /// Copy converted to another voxel type.
  Volume converted(VoxelType t) const;

  /// World bounding box of the voxel nodes.
  Box world_bounds() const;

 private:
  VoxelType type_ = VoxelType::f32;
  Dims dims_;
  Geometry geometry_;
  FrameSource frame_source_;
  std::map<std::string, std::string> keys_;
  std::vector<unsigned char> bytes_;
};

/// Volume keys of a signed distance whose values on one side of the surface
/// are exact only up to this distance from it (world units; beyond, they are
/// correctly signed estimates within about a voxel): the positive side
/// (tighten --outside-band: outside the material) and the negative side
/// (with --positive-inside). Checked by the tools that read farther out.
inline constexpr const char* kExactPositiveKey = "pm_exact_positive";
inline constexpr const char* kExactNegativeKey = "pm_exact_negative";
/// How far from the surface `sdf`'s values are exact on its positive side
/// (positive_side) or its negative side: the key's value, or infinity when
/// the volume has no such key. \throw InputError naming `what` when the
/// key's value is not a number > 0.
double exact_within(const Volume& sdf, bool positive_side, const std::string& what);

/// The same volume with every flipped axis stored the other way round, for
/// formats and libraries that hold only positive per-axis spacings (INR,
/// CGAL's images): for diagonal directions, each axis with a negative step
/// (x and y of a RAS NIfTI in LPS) gets its voxels in reverse order and the
/// origin at its other end, so every voxel keeps its world position. A volume
/// without flipped axes is returned unchanged.
/// \throw InputError naming `what` when the directions are not diagonal (oblique axes).
Volume with_positive_steps(const Volume& v, const std::string& what);

/// Throws InputError naming `what` (usually a file name) if any voxel is NaN/Inf.
void require_finite(const Volume& v, const std::string& what);

/// min and max voxel value.
struct ValueRange {
  double lo = 0, hi = 0;
};
ValueRange value_range(const Volume& v);
/// The smallest integer voxel type holding every value of an integer volume:
/// uint8, uint16, uint32 (no negative values) or int8, int16, int32; the
/// volume's own type when none of these does (64-bit values).
/// \throw InputError for a volume of float or double voxels.
VoxelType smallest_integer_type(const Volume& v);

/// `v` grown by n voxels on every side of every axis, the new voxels set to
/// `value`; the origin moves by -n steps along each axis so every old voxel
/// keeps its world position. \throw InputError when the padded size
/// overflows (as the Volume constructor).
Volume padded(const Volume& v, std::size_t n, double value);

}  // namespace pm

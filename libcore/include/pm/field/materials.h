#pragma once
// A set of materials for Chapter 6 (SPEC §6): one field per material, the
// material at a point being the one whose indicator is largest there.
//
// Sign convention: every stored field d_i is signed-distance-like and
// NEGATIVE inside material i (as `tighten` and `volconv --distance` write);
// the indicator functions of the dissertation are f_i = -d_i (positive inside).
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/base/volume.h"
#include "pm/field/field.h"
#include "pm/field/kernels.h"

namespace pm {

/// The reconstruction kernel type of pm/field/kernels.h (Catmull-Rom is the
/// Chapter-6 default).
using Kernel = KernelType;

struct MaterialSet {
  std::vector<int> labels;                                 ///< label of material i (distinct)
  std::vector<std::shared_ptr<const ScalarField>> fields;  ///< d_i, negative inside material i
  std::size_t size() const { return labels.size(); }
  /// f_i = -d_i(p) for all i (positive inside material i), into out (size()).
  void indicators(const Vec3& p, double* out) const;
  /// Index i of the largest f_i at p (ties: smallest index).
  std::size_t argmax(const Vec3& p) const;
  /// Label of the material at p: labels[argmax(p)].
  int label_at(const Vec3& p) const { return labels[argmax(p)]; }
  /// Index of `label`, or size() when absent.
  std::size_t index_of(int label) const;
  /// Intersection of the fields' domains (world units).
  Box domain() const;
  /// Smallest of the fields' resolutions (world units).
  double resolution() const;
};

/// Value bounds of every field of the set over blocks of `block` voxels
/// (ScalarField::value_bounds; null where a field has none).
using MaterialBounds = std::vector<std::shared_ptr<const ValueBounds>>;
MaterialBounds material_bounds(const MaterialSet& m, int block = 4);

/// m.argmax(p), the same index, without evaluating the materials whose
/// bounds put them below another material's lower bound at p.
std::size_t argmax_bounded(const MaterialSet& m, const MaterialBounds& b, const Vec3& p);

/// The label of the argmax at every node of `grid` (its dims and geometry;
/// int32 voxels): `volconv --argmax`. Bounded and parallel over slices; the
/// same labels as label_at at each node.
Volume argmax_labels(const MaterialSet& m, const Volume& grid);

/// The region of material i as a field negative inside it:
/// g_i(x) = d_i(x) - min_{j != i} d_j(x) (the best other indicator minus
/// f_i), zero on the interfaces of i. Its gradient is the difference of the
/// two fields' gradients. Shares the set's fields. \pre i < set.size() >= 2.
std::shared_ptr<const ScalarField> material_region_field(const MaterialSet& set, std::size_t i);

/// Largest number of materials load_materials accepts (one float volume each).
constexpr std::size_t kMaxMaterials = 256;

/// Build a material set from
///  * "L1=path1,L2=path2,..." : one volume per material, a signed distance
///    (or any field) NEGATIVE inside material Li; write "L=+path" for a field
///    that is POSITIVE inside (indicator functions such as Cleaver's, material
///    = argmax), which is then negated; or
///  * a single label-map path (integer voxels, or float voxels with integral
///    values): every label present is a material (label 0 included) whose
///    field is the signed distance of its mask (pm::mask_signed_distance),
///    computed in memory.
/// Fields are reconstructed with `kernel` for values and derivatives.
/// \throw UsageError for a malformed spec (empty entry, non-integer label);
/// InputError for fewer than 2 materials, duplicate labels, volumes whose
/// dims or geometry differ (naming both files and the values), a label map
/// with non-integer values or more than kMaxMaterials labels, NaN voxels;
/// IoError for unreadable files.
MaterialSet load_materials(const std::string& spec, Kernel kernel = KernelType::catmull_rom);

/// The same from a label map already in memory (`what` names it in messages).
MaterialSet materials_from_labels(const Volume& labels, Kernel kernel = KernelType::catmull_rom,
                                  const std::string& what = "labels");

}  // namespace pm

#pragma once
// Do the particles sample every component of the isosurface? Components come
// from the marching-cubes seeds (mcinit, vertex scalar "component"), which
// find every component of the field's surface without particles.
#include <cstddef>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/mesh.h"

namespace pm {

struct ComponentCoverage {
  int component = 0;        ///< mcinit component id
  std::size_t seeds = 0;    ///< its marching-cubes seeds
  std::size_t points = 0;   ///< points whose nearest seed belongs to it
  Box bounds;               ///< bounding box of its seeds, world units
};

/// Assign every point to the component of its nearest seed (ties: lowest
/// seed index) and count, per component, seeds and points. A component with
/// points == 0 has no particle anywhere near it: the particles miss it.
/// Sorted by component id.
/// \throw InputError when `seeds` has no vertex scalar "component" or no vertices.
std::vector<ComponentCoverage> component_coverage(const Mesh& seeds, const std::vector<Vec3>& points);

}  // namespace pm

#pragma once
// Polygon soups (points + index lists, as mesh readers produce them) to Mesh.
#include <cstddef>
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/base/vec.h"

namespace pm {

/// A Mesh from a polygon soup: polygons (each a list of vertex indices, at
/// least 3) are fan-triangulated (v0 v1 v2, v0 v2 v3, ...).
/// \throw InputError "fn: "path": polygon i ..." when a polygon has fewer than
/// 3 vertices or an index >= points.size(), or there are more than INT_MAX points.
/// `polygon_sizes` (when not null) receives each polygon's vertex count, in
/// order: polygon k became its n - 2 fan triangles (pm::fans_to_polygons).
Mesh mesh_from_polygons(std::vector<Vec3> points, const std::vector<std::vector<std::size_t>>& polygons,
                        const std::string& fn, const std::string& path, std::vector<int>* polygon_sizes = nullptr);

}  // namespace pm

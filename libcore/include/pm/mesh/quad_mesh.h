#pragma once
// Quad-dominant surface meshes from two-type particle packings (SPEC §7,
// "Quad packing", issue #20). The particles of `particles --quads` settle
// towards a checkerboard of two types; in the Delaunay triangulation of such
// a packing the edges between like particles are the diagonals of the
// checkerboard squares, so dropping them pairs the two triangles on either
// side into a quad. Triangles left over (defects of the checkerboard) are
// paired across any edge where the quad is good enough, greedily, best quad
// first; the rest stay triangles. Merging two triangles across their shared
// edge keeps every other edge, so a closed manifold triangle mesh gives a
// closed manifold polygon mesh with the same vertices and topology.
// World units; angles in degrees.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/base/stats.h"

namespace pm {

struct QuadParams {
  /// A merge is allowed only when every corner angle of the quad lies in
  /// [90 - max_corner_deviation, 90 + max_corner_deviation] (so the quad is
  /// convex) and the two triangles' normals differ by at most max_fold.
  double max_corner_deviation = 60;
  double max_fold = 40;
  /// Pair the triangles left after the like-edge merges across unlike edges
  /// too (else they stay triangles).
  bool pair_leftovers = true;
  /// Then, from every triangle still alone, augmenting paths through at most
  /// this many taken quads (0 = none): one more quad per path, each quad of
  /// the new pairing a candidate that passed the tests above.
  int augment_depth = 3;
  /// ... using only candidate quads whose corners are within this of 90°,
  /// degrees (more quads at worse corners above it: on the brain mask, 60°
  /// gains 0.3% quads and loses 0.14% of the corners within 90 ± 20°).
  double augment_max_deviation = 40;
};

struct QuadResult {
  PolyMesh mesh;
  std::size_t like_edges = 0;        ///< interior edges between like particles
  std::size_t like_merges = 0;       ///< quads made across a like edge
  std::size_t leftover_merges = 0;   ///< quads made across an unlike edge from leftover triangles
  std::size_t triangles_left = 0;    ///< triangles kept as triangles
  std::size_t augmented = 0;         ///< augmenting paths applied (each one more quad)
};

/// `tri`: a triangle mesh whose vertices are the particles; `type`: #V types
/// (0 or 1). Deterministic (candidates in a fixed order).
/// \throw InputError when `type` does not match the vertices or an edge has
/// more than two triangles (not a manifold).
QuadResult quad_dominant(const Mesh& tri, const std::vector<int>& type, const QuadParams& p = {});

/// Quality of a polygon mesh: the issue #20 figures.
struct QuadQuality {
  std::size_t vertices = 0, faces = 0, quads = 0, triangles = 0;
  /// Corner angles of the quads: min, max, 10° histogram (18 bins), and the
  /// share of corners within 90 ± 20°.
  double corner_min = 180, corner_max = 0;
  std::array<std::size_t, 18> corner_hist{};
  std::size_t corners = 0, corners_70_110 = 0;
  /// Scaled Jacobian of each quad: the smallest over its corners of
  /// (e1 × e2)·n / (|e1| |e2|), n the quad's mean normal (1 = square, <= 0
  /// folded or non-convex).
  double jacobian_min = 1, jacobian_mean = 0;
  /// Vertex valence (edges at a vertex): the share of valence 4 and the count
  /// of the others (irregular vertices), over the vertices in a face.
  std::size_t valence4 = 0, irregular = 0;
  /// Edges in one face (holes) and in three or more (non-manifold).
  std::size_t boundary_edges = 0, nonmanifold_edges = 0;
  double quad_share() const { return faces ? double(quads) / double(faces) : 0.0; }
  double corner_share_70_110() const { return corners ? double(corners_70_110) / double(corners) : 0.0; }
  double valence4_share() const {
    return valence4 + irregular ? double(valence4) / double(valence4 + irregular) : 0.0;
  }
};

QuadQuality quad_quality(const PolyMesh& m);

/// The polygon-mesh measures quad_quality and the quad smoother share.
/// Angle at v between the edges to prev and next, degrees (0 when an edge is degenerate).
double corner_angle_deg(const Vec3& prev, const Vec3& v, const Vec3& next);
/// Normal of face f of x (a triangle, or a quad when f[3] >= 0), not
/// normalised: the sum of its corners' cross products (a quad's mean plane).
Vec3 polygon_normal(const std::vector<Vec3>& x, const std::array<int, 4>& f);
/// Scaled Jacobian of face f (quads; 1 for triangles): the smallest over its
/// corners of (e1 × e2)·n / (|e1| |e2|), n = polygon_normal; -1 when degenerate.
double polygon_scaled_jacobian(const std::vector<Vec3>& x, const std::array<int, 4>& f);
/// Key of the undirected edge (a, b), the smaller index in the high word.
std::uint64_t undirected_edge_key(int a, int b);
Json to_json(const QuadQuality& q);

}  // namespace pm

#pragma once
// CPU rendering of point sets and triangle meshes to an RGB image, for looking
// at results (SPEC §3.8): oriented disks or surface splatting for points,
// z-buffered shaded triangles for meshes. Orthographic camera fitted to the
// bounding box. Deterministic (single-threaded, no randomness).
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/mesh.h"
#include "pm/io/png.h"

namespace pm {

struct RenderParams {
  int width = 800, height = 800;  ///< image size, pixels, each in [1, 8192]
  /// Camera direction, degrees: azimuth about the up axis (0 = looking from
  /// the +first horizontal axis, e.g. +x when up is z), elevation above the
  /// horizontal plane (90 = looking straight down).
  double azimuth_deg = 30, elevation_deg = 20;
  /// "auto" (mesh when there are faces, else splats), "disks", "splats", "mesh".
  /// disks/splats on a mesh draw its vertices.
  std::string mode = "auto";
  /// Vertex scalar (viridis colormap over its finite min..max) or face int
  /// property (categorical palette, value modulo 12; mesh mode only); "" = plain.
  std::string color_by;
  /// Disk/splat radius, world units; 0 = auto, per point: the distance to
  /// its 6th nearest neighbour (about the local spacing; clamped to 0.25..4
  /// times the mean of that distance) times 0.9 (disks) or 1.0 (splats).
  double radius = 0;
  Vec3 background{1, 1, 1};  ///< RGB, each in [0, 1]
  /// Mesh mode: darken pixels within about a pixel of a triangle edge
  /// (wireframe over shading, hidden edges stay hidden). Off by default: at
  /// the default size it turns meshes of more than ~100k faces dark.
  bool edges = false;
  std::string up = "z";  ///< world axis that points up on screen: "x", "y" or "z"
  /// With a face int colour (color_by): a key in the top-left corner, one flat
  /// swatch per value present with its name: "A-B" (label_a-label_b) when the
  /// mesh is an interface mesh (face ints label_a, label_b), else the value.
  bool legend = false;
  /// Clip (mesh mode): "" = none, or "x", "y", "z" optionally with ":F", the
  /// plane at fraction F (0..1, default 0.5) of the bounding box along that world
  /// axis; faces whose centroid lies on the camera's side of it are not drawn,
  /// so inner materials show. The camera stays fitted to the whole mesh.
  std::string clip;
};

/// Colour of face category v (the palette `color_by` uses for face ints): 12 fixed colours for
/// v in [0, 12), then hues stepped by the golden angle with alternating lightness, so that the
/// many interfaces of a label map with dozens of tissues do not share colours.
Vec3 category_color(int v);

/// Orthographic camera: a sphere around the points (centred on their bounding
/// box, radius: the farthest point plus a margin), seen along `forward`, fills
/// the smaller image side with a 5% margin, so the framing does not depend on
/// the view angles.
struct Camera {
  Vec3 center;                  ///< box centre, world units
  Vec3 right, up, forward;      ///< orthonormal; forward points into the screen
  double scale = 1;             ///< pixels per world unit
  int width = 0, height = 0;    ///< pixels
  /// Pixel x (right), pixel y (down, 0 = top edge), depth along forward
  /// (world units, relative to the centre; smaller = nearer).
  Vec3 project(const Vec3& p) const {
    const Vec3 d = p - center;
    return {0.5 * width + scale * dot(d, right), 0.5 * height - scale * dot(d, up), dot(d, forward)};
  }
};

/// Camera of `params` (angles, up axis, size) for the finite points of
/// `points`; `margin` (world units) is added to the sphere's radius.
/// \throw UsageError for a bad size or up axis.
Camera fit_camera(const std::vector<Vec3>& points, const RenderParams& params, double margin = 0);

/// The camera render() uses for m: fit_camera over the vertices, with the
/// largest disk/splat radius as margin in the point modes.
/// \throw as render().
Camera render_camera(const Mesh& m, const RenderParams& params);

/// For each point, the distance to its k-th nearest other distinct point
/// (k >= 1), found with a uniform grid (near-linear time); 0 where it lies far
/// beyond the typical spacing (isolated points) or does not exist.
std::vector<double> nearest_neighbor_distances(const std::vector<Vec3>& points, int k);

/// Mean of the positive nearest_neighbor_distances(points, 1); 0 for fewer
/// than 2 distinct points.
double mean_nearest_neighbor_distance(const std::vector<Vec3>& points);

/// The plane of params.clip ("x", "y:0.3", ...) through `points`: world
/// axis (0, 1, 2), position (world units: the fraction along the points'
/// bounding box) and the side that is left out: +1 when it is the side of
/// larger coordinates (where the camera looks from), else -1. A point p is
/// left out when (p[axis] - position) * removed_side > 0.
/// \pre params.clip is not empty. \throw UsageError for a bad clip.
struct ClipPlane {
  int axis = 0;
  double position = 0;
  double removed_side = 1;
};
ClipPlane clip_plane(const std::vector<Vec3>& points, const RenderParams& params, const Camera& cam);

/// Render m with params. In the point modes normals are taken as oriented
/// outward (from nx ny nz, else computed from the faces): points facing away
/// from the camera are culled. Points without normals (and no faces) are drawn
/// as camera-facing disks. Mesh triangles are shaded two-sided (either winding).
/// \throw UsageError for bad params (size, mode, up, clip); InputError when m has no
/// vertices, fails validate(), mode "mesh" has no faces, or color_by names no
/// property (the message lists the available ones).
/// `edge_flags` (mesh mode with `edges`; #F or null = every edge): bit k of
/// face f set draws its edge faces[f][k] -> faces[f][(k+1) % 3], so the
/// diagonals of fan-triangulated quads stay hidden (polygon_edge_flags).
Image render(const Mesh& m, const RenderParams& params, const std::vector<std::uint8_t>* edge_flags = nullptr);

/// The edge flags that draw only the polygon sides of a mesh fan-triangulated
/// as (v0, vk, vk+1) from polygons of `polygon_sizes` vertices (in order).
/// \throw InputError when the sizes do not add up to `faces` triangles.
std::vector<std::uint8_t> polygon_edge_flags(const std::vector<int>& polygon_sizes, std::size_t faces);

}  // namespace pm

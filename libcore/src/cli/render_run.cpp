#include "pm/cli/render_run.h"

#include <algorithm>
#include <cstdio>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/stats.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/png.h"
#include "pm/io/poly_mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/render/render.h"
#include "pm/render/tet_render.h"

namespace pm {

namespace {

// The camera and drawing parameters every render records in its stats.
Json view_parameters(const RenderParams& p) {
  return {{"size", {p.width, p.height}}, {"azimuth_deg", p.azimuth_deg}, {"elevation_deg", p.elevation_deg},
          {"edges", p.edges},           {"up", p.up},                   {"legend", p.legend},
          {"clip", p.clip}};
}

}  // namespace

void add_render_options(CLI::App& app, RenderRun& r) {
  app.add_option("input", r.input,
                 "Point set or mesh (.ply .vtk .mesh .off .obj .stl) or tetrahedral mesh (.mesh .vtu .vtk .msh)")
      ->required();
  app.add_option("-o,--output", r.output, "Output image (.png)")->required();
  app.add_option("--azimuth", r.params.azimuth_deg, "Camera angle about the up axis, degrees")->capture_default_str();
  app.add_option("--elevation", r.params.elevation_deg, "Camera angle above the horizontal, degrees")
      ->capture_default_str();
  app.add_option("--size", r.size, "Image size WxH, pixels (each 1..8192)")->capture_default_str();
  app.add_option("--mode", r.params.mode, "auto (mesh if faces, else splats), disks, splats or mesh")
      ->check(CLI::IsMember({"auto", "disks", "splats", "mesh"}))
      ->capture_default_str();
  app.add_option("--color-by", r.params.color_by,
                 "Colour by a vertex property (viridis) or face int property (categories); default plain "
                 "(tetrahedral meshes: always by material)");
  app.add_option("--radius", r.params.radius,
                 "Disk/splat radius, world units (0 = auto per point: about the local spacing, the distance "
                 "to the 6th nearest neighbour, x0.9 for disks, x1.0 for splats)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--edges", r.params.edges,
               "Mesh mode: draw the edges over the shading (polygon files: the polygon sides only)");
  app.add_flag("--legend", r.params.legend,
               "With a face property colour: a key in the top-left corner naming each colour (interface "
               "meshes: the material pair label_a-label_b; tetrahedral meshes: each material shown)");
  app.add_option("--clip", r.params.clip,
                 "Mesh mode: cut at the plane x, y or z (optionally :F, the fraction 0..1 of the bounding box, "
                 "default 0.5) and leave out the faces (tetrahedra: the whole tetrahedra, by centroid) on the "
                 "camera's side, so inner materials show");
  app.add_option("--up", r.params.up, "World axis pointing up on screen: x, y or z")
      ->check(CLI::IsMember({"x", "y", "z"}))
      ->capture_default_str();
}

void run_render(RenderRun& r) {
  const std::string &in = r.input, &out = r.output, &size = r.size;
  RenderParams& p = r.params;
  check_output_path(out, OutputKind::png, "--output");
  char x = 0, extra = 0;
  if (std::sscanf(size.c_str(), "%d%c%d%c", &p.width, &x, &p.height, &extra) != 3 || (x != 'x' && x != 'X'))
    throw UsageError("--size " + quote(size) + ": expected WxH, e.g. 800x600");
  if (p.width < 1 || p.width > 8192 || p.height < 1 || p.height > 8192)
    throw UsageError("--size " + size + ": expected each side in 1..8192 pixels");

  if (is_tet_mesh_file(in)) {
    const LabelledTets t = read_tet_mesh(in);
    Image img;
    {
      ScopedStage stage("render");
      img = render_tets(t, p);
    }
    write_png(img, out);
    auto& s = stats();
    s["inputs"] = {in};
    s["parameters"] = view_parameters(p);
    s["counts"] = {{"vertices", t.vertices.size()}, {"tetrahedra", t.tets.size()}};
    return;
  }
  // Polygon files keep their quads: only the polygon sides are drawn as
  // edges, and the faces can be coloured by `polygon_sides` (3 or 4).
  std::vector<int> sides;
  Mesh m = read_mesh_polygons(in, sides);
  std::vector<std::uint8_t> flags;
  if (std::any_of(sides.begin(), sides.end(), [](int n) { return n > 3; })) {
    flags = polygon_edge_flags(sides, m.faces.size());
    auto& f = m.face_ints["polygon_sides"];
    for (const int n : sides) f.insert(f.end(), std::size_t(n - 2), n);
  }
  if (m.vertices.empty()) throw InputError(quote(in) + ": no vertices; expected a point set or mesh");
  for (std::size_t k = 0; k < m.vertices.size(); ++k)
    if (!is_finite(m.vertices[k]))
      throw InputError(quote(in) + ": vertex " + std::to_string(k) +
                       " is not finite; expected finite "
                       "coordinates");
  if (!p.color_by.empty() && !m.vertex_scalars.count(p.color_by) && !m.face_ints.count(p.color_by)) {
    std::string avail;
    for (const auto& kv : m.vertex_scalars) avail += (avail.empty() ? "" : ", ") + kv.first;
    for (const auto& kv : m.face_ints) avail += (avail.empty() ? "" : ", ") + kv.first + " (face)";
    throw InputError(quote(in) + " has no property " + quote(p.color_by) +
                     "; available: " + (avail.empty() ? "none" : avail));
  }
  Image img;
  {
    ScopedStage stage("render");
    img = render(m, p, flags.empty() ? nullptr : &flags);
  }
  write_png(img, out);
  auto& s = stats();
  s["inputs"] = {in};
  s["parameters"] = view_parameters(p);
  s["parameters"]["mode"] = p.mode;
  s["parameters"]["color_by"] = p.color_by;
  s["parameters"]["radius"] = p.radius;
  s["counts"] = {{"vertices", m.vertices.size()}, {"faces", m.faces.size()}};
}

}  // namespace pm

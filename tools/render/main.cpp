// render: draw a point set or mesh to a PNG (oriented disks, surface splats or
// shaded triangles) for looking at results.
#include <algorithm>
#include <cstdio>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/poly_mesh.h"
#include "pm/io/png.h"
#include "pm/io/tet_mesh.h"
#include "pm/render/render.h"
#include "pm/render/tet_render.h"
#include "pm/io/output_path.h"

int main(int argc, char** argv) {
  pm::Tool tool("render",
                "Render a point set or mesh (.ply .vtk .mesh .off .obj .stl) to a PNG with an orthographic camera "
                "fitted to its bounding box. Points are drawn as oriented disks or blended surface splats in their "
                "tangent planes (normals from nx ny nz, else from faces); meshes as shaded triangles. A tetrahedral "
                "mesh (.mesh .vtu .vtk .msh with tetrahedra) is drawn as its outer boundary coloured by material, "
                "or with --clip as a cut: the tetrahedra on the camera's side of the plane are removed whole "
                "(a crinkle clip, as ParaView's 'keep whole cells') and the faces of the rest coloured by material.",
                "render particles.ply -o view.png --azimuth 45 --elevation 30 --size 1024x768 --color-by curvature\n"
                "  render interfaces.ply -o cut.png --color-by pair --legend --clip x   # inner materials\n"
                "  render volume.vtu -o cut.png --clip y:0.5 --legend --edges   # tetrahedra cut at mid-y");
  std::string in, out, size = "800x800";
  pm::RenderParams p;
  tool.app.add_option("input", in,
                      "Point set or mesh (.ply .vtk .mesh .off .obj .stl) or tetrahedral mesh (.mesh .vtu .vtk .msh)")
      ->required();
  tool.app.add_option("-o,--output", out, "Output image (.png)")->required();
  tool.app.add_option("--azimuth", p.azimuth_deg, "Camera angle about the up axis, degrees")->capture_default_str();
  tool.app.add_option("--elevation", p.elevation_deg, "Camera angle above the horizontal, degrees")
      ->capture_default_str();
  tool.app.add_option("--size", size, "Image size WxH, pixels (each 1..8192)")->capture_default_str();
  tool.app.add_option("--mode", p.mode, "auto (mesh if faces, else splats), disks, splats or mesh")
      ->check(CLI::IsMember({"auto", "disks", "splats", "mesh"}))
      ->capture_default_str();
  tool.app.add_option("--color-by", p.color_by,
                      "Colour by a vertex property (viridis) or face int property (categories); default plain "
                      "(tetrahedral meshes: always by material)");
  tool.app.add_option("--radius", p.radius,
                      "Disk/splat radius, world units (0 = auto per point: about the local spacing, the distance "
                      "to the 6th nearest neighbour, x0.9 for disks, x1.0 for splats)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  tool.app.add_flag("--edges", p.edges, "Mesh mode: draw triangle edges over the shading");
  tool.app.add_flag("--legend", p.legend,
                    "With a face property colour: a key in the top-left corner naming each colour (interface "
                    "meshes: the material pair label_a-label_b; tetrahedral meshes: each material shown)");
  tool.app.add_option("--clip", p.clip,
                      "Mesh mode: cut at the plane x, y or z (optionally :F, the fraction 0..1 of the bounding box, "
                      "default 0.5) and leave out the faces (tetrahedra: the whole tetrahedra, by centroid) on the "
                      "camera's side, so inner materials show");
  tool.app.add_option("--up", p.up, "World axis pointing up on screen: x, y or z")
      ->check(CLI::IsMember({"x", "y", "z"}))
      ->capture_default_str();

  return tool.run(argc, argv, [&] {
    pm::check_output_path(out, pm::OutputKind::png, "--output");
    char x = 0, extra = 0;
    if (std::sscanf(size.c_str(), "%d%c%d%c", &p.width, &x, &p.height, &extra) != 3 || (x != 'x' && x != 'X'))
      throw pm::UsageError("--size " + pm::quote(size) + ": expected WxH, e.g. 800x600");
    if (p.width < 1 || p.width > 8192 || p.height < 1 || p.height > 8192)
      throw pm::UsageError("--size " + size + ": expected each side in 1..8192 pixels");

    if (pm::is_tet_mesh_file(in)) {
      const pm::LabelledTets t = pm::read_tet_mesh(in);
      pm::Image img;
      {
        pm::ScopedStage stage("render");
        img = pm::render_tets(t, p);
      }
      pm::write_png(img, out);
      auto& s = pm::stats();
      s["inputs"] = {in};
      s["parameters"] = {{"size", {p.width, p.height}}, {"azimuth_deg", p.azimuth_deg},
                         {"elevation_deg", p.elevation_deg}, {"edges", p.edges}, {"up", p.up},
                         {"legend", p.legend}, {"clip", p.clip}};
      s["counts"] = {{"vertices", t.vertices.size()}, {"tetrahedra", t.tets.size()}};
      return;
    }
    // Polygon files keep their quads: only the polygon sides are drawn as
    // edges, and the faces can be coloured by `polygon_sides` (3 or 4).
    std::vector<int> sides;
    pm::Mesh m = pm::read_mesh_polygons(in, sides);
    std::vector<std::uint8_t> flags;
    if (std::any_of(sides.begin(), sides.end(), [](int n) { return n > 3; })) {
      flags = pm::polygon_edge_flags(sides, m.faces.size());
      auto& f = m.face_ints["polygon_sides"];
      for (const int n : sides) f.insert(f.end(), std::size_t(n - 2), n);
    }
    if (m.vertices.empty()) throw pm::InputError(pm::quote(in) + ": no vertices; expected a point set or mesh");
    for (std::size_t k = 0; k < m.vertices.size(); ++k)
      if (!pm::is_finite(m.vertices[k]))
        throw pm::InputError(pm::quote(in) + ": vertex " + std::to_string(k) + " is not finite; expected finite "
                             "coordinates");
    if (!p.color_by.empty() && !m.vertex_scalars.count(p.color_by) && !m.face_ints.count(p.color_by)) {
      std::string avail;
      for (const auto& kv : m.vertex_scalars) avail += (avail.empty() ? "" : ", ") + kv.first;
      for (const auto& kv : m.face_ints) avail += (avail.empty() ? "" : ", ") + kv.first + " (face)";
      throw pm::InputError(pm::quote(in) + " has no property " + pm::quote(p.color_by) +
                           "; available: " + (avail.empty() ? "none" : avail));
    }
    pm::Image img;
    {
      pm::ScopedStage stage("render");
      img = pm::render(m, p, flags.empty() ? nullptr : &flags);
    }
    pm::write_png(img, out);
    auto& s = pm::stats();
    s["inputs"] = {in};
    s["parameters"] = {{"size", {p.width, p.height}}, {"azimuth_deg", p.azimuth_deg},
                       {"elevation_deg", p.elevation_deg}, {"mode", p.mode}, {"color_by", p.color_by},
                       {"radius", p.radius}, {"edges", p.edges}, {"up", p.up},
                       {"legend", p.legend}, {"clip", p.clip}};
    s["counts"] = {{"vertices", m.vertices.size()}, {"faces", m.faces.size()}};
  });
}

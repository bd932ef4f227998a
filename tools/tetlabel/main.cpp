// tetlabel: mesh particles by labelled Delaunay tetrahedra (TetGen): every
// tetrahedron is inside or outside by the field at its circumcentre; the
// faces between inside and outside form the surface.
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/ops/tetlabel.h"

int main(int argc, char** argv) {
  pm::Tool tool("tetlabel",
                "Triangulate surface particles: Delaunay-tetrahedralise them (TetGen), label each tetrahedron "
                "inside (F < iso) or outside by the field at its circumcentre, and write the faces between "
                "inside and outside as a closed, outward-oriented triangle mesh (PLY, OBJ, OFF, STL by "
                "extension). World units throughout.",
                "tetlabel points.ply -i brain_sdf.nrrd --iso 0 -o surface.ply --tets brain.mesh");
  std::string points, out, tets, inside = "auto";
  bool repair = true;
  pm::FieldOptions fo;
  tool.app.add_option("points", points, "Particles (PLY, OFF, OBJ, STL vertices), world units")->required();
  pm::add_field_options(tool.app, fo);
  tool.app.add_option("-o,--output", out, "Surface mesh to write (.ply .obj .off .stl)")->required();
  tool.app.add_option("--inside", inside,
                      "Which side is the material: below (F < iso, distance fields), above (F > iso, masks, CT "
                      "intensities) or auto (the side the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  tool.app.add_flag("--repair,!--no-repair", repair,
                    "Relabel tetrahedra at pinched vertices so the surface is a manifold (default on)");
  tool.app.add_option("--tets", tets, "Also write the inside tetrahedra as a MEDIT .mesh");
  return tool.run(argc, argv, [&] {
    auto& st = pm::stats();
    st["inputs"] = {points, fo.input.empty() ? fo.implicit : fo.input};
    const pm::LoadedField lf = pm::load_field(fo);
    const pm::Mesh pts = pm::read_mesh(points);
    if (pts.vertices.size() < 4)
      throw pm::InputError(pm::quote(points) + ": " + std::to_string(pts.vertices.size()) +
                           " points; expected at least 4 particles");
    pm::TetMesh tm;
    {
      pm::ScopedStage s("delaunay");
      try {
        tm = pm::delaunay(pts.vertices);
      } catch (const pm::InputError& e) {
        throw pm::InputError(pm::quote(points) + ": " + e.what());
      }
    }
    pm::TetLabelStats ls;
    {
      pm::ScopedStage s("label");
      const pm::ScalarField& f = *lf.field;
      const double iso = lf.iso;
      // Circumcentres of hull tetrahedra can lie far outside the volume, where
      // a reconstructed field only replicates its border: outside the domain
      // is outside the material.
      const pm::Box dom = f.domain();
      const bool below = inside == "auto" ? pm::material_below_iso(f, iso) : inside == "below";
      st["parameters"] = {{"iso", iso}, {"inside", below ? "below" : "above"}};
      ls = pm::label_tets(tm, [&](const pm::Vec3& x) {
        if (!dom.contains(x)) return 0;
        const double v = f.value(x);
        return (below ? v < iso : v > iso) ? 1 : 0;
      });
    }
    std::size_t relabelled = 0;
    if (repair) {
      pm::ScopedStage s("manifold");
      relabelled = pm::make_manifold(tm, 1, 0);
    }
    pm::Mesh surf = pm::material_surface(tm, 1, 0);
    if (surf.faces.empty())
      throw pm::InputError(pm::quote(points) + ": no tetrahedron is inside the surface F < " +
                           std::to_string(lf.iso) + "; expected particles sampling the isosurface");
    if (pts.has_normals()) {
      surf.normals.resize(surf.vertices.size());
      const auto& idx = surf.vertex_scalars.at("index");
      for (std::size_t i = 0; i < surf.vertices.size(); ++i) surf.normals[i] = pts.normals[std::size_t(idx[i])];
    }
    const pm::MeshTopology t = pm::mesh_topology(surf);
    const std::size_t buried = pts.vertices.size() - t.vertices;
    if (!t.closed_manifold())
      pm::warn("the surface is not a closed manifold: " + std::to_string(t.boundary_edges) + " boundary edges, " +
               std::to_string(t.nonmanifold_edges) + " non-manifold edges, " +
               std::to_string(t.nonmanifold_vertices) + " non-manifold vertices");
    if (buried > 0)
      pm::warn(std::to_string(buried) + " particles are not on the surface (off the isosurface, or too close)");
    pm::write_mesh(surf, out);
    if (!tets.empty()) pm::write_medit(tm, 0, tets);
    pm::info(std::to_string(t.vertices) + " vertices, " + std::to_string(t.faces) + " triangles, " +
             std::to_string(t.components) + " component(s), genus " + std::to_string(t.genus));
    st["outputs"] = tets.empty() ? pm::Json{out} : pm::Json{out, tets};
    st["counts"] = {{"particles", pts.vertices.size()}, {"tetrahedra", ls.tets}, {"degenerate_tetrahedra", ls.flat},
                    {"relabelled_for_manifold", relabelled},
                    {"vertices", t.vertices}, {"faces", t.faces}, {"particles_not_on_surface", buried},
                    {"components", t.components}, {"genus", t.genus}, {"boundary_edges", t.boundary_edges},
                    {"nonmanifold_edges", t.nonmanifold_edges}, {"nonmanifold_vertices", t.nonmanifold_vertices}};
  });
}

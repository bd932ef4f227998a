// tetlabel: mesh particles by labelled Delaunay tetrahedra (TetGen): every
// tetrahedron is inside or outside by the field at its circumcentre; the
// faces between inside and outside form the surface.
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/surface_improve.h"
#include "pm/cli/material_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/mesh/tetlabel.h"
#include "pm/mesh/tetlabel_materials.h"
#include "pm/cli/frame_option.h"
#include "pm/io/output_path.h"
#include "pm/io/tet_mesh.h"

namespace {

// Copy the particles' vertex scalars (junction, label_a, ...) onto a mesh
// made from them (vertex scalar "index" = particle index).
void copy_point_scalars(const pm::Mesh& pts, pm::Mesh& m) {
  const auto& idx = m.vertex_scalars.at("index");
  for (const auto& [name, vals] : pts.vertex_scalars) {
    if (name == "index") continue;
    std::vector<double> v(m.vertices.size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = vals[std::size_t(idx[i])];
    m.vertex_scalars[name] = std::move(v);
  }
}

// Drop particles closer than `tol` to an earlier one (TetGen refuses
// duplicates, e.g. two seeds converged onto one quadruple point); vertex
// scalars follow. Returns the number dropped.
std::size_t drop_duplicates(pm::Mesh& pts, double tol) {
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid;
  auto cell = [&](const pm::Vec3& p, int dx, int dy, int dz) {
    const auto c = [&](double v, int d) { return std::uint64_t(std::int64_t(std::floor(v / tol)) + d) & 0x1fffff; };
    return (c(p.x, dx) << 42) | (c(p.y, dy) << 21) | c(p.z, dz);
  };
  std::vector<std::size_t> keep;
  for (std::size_t i = 0; i < pts.vertices.size(); ++i) {
    bool dup = false;
    for (int dx = -1; dx <= 1 && !dup; ++dx)
      for (int dy = -1; dy <= 1 && !dup; ++dy)
        for (int dz = -1; dz <= 1 && !dup; ++dz) {
          auto it = grid.find(cell(pts.vertices[i], dx, dy, dz));
          if (it == grid.end()) continue;
          for (std::size_t j : it->second)
            if (pm::norm(pts.vertices[j] - pts.vertices[i]) <= tol) dup = true;
        }
    if (dup) continue;
    grid[cell(pts.vertices[i], 0, 0, 0)].push_back(i);
    keep.push_back(i);
  }
  const std::size_t dropped = pts.vertices.size() - keep.size();
  if (dropped == 0) return 0;
  pm::Mesh out;
  for (std::size_t i : keep) {
    out.vertices.push_back(pts.vertices[i]);
    if (pts.has_normals()) out.normals.push_back(pts.normals[i]);
    for (const auto& [name, v] : pts.vertex_scalars) out.vertex_scalars[name].push_back(v[i]);
  }
  pts = std::move(out);
  return dropped;
}

// TetGen's Delaunay tetrahedralisation of the particles (a timed stage);
// TetGen's complaints name the point file.
pm::TetMesh delaunay_of(const std::string& points, const pm::Mesh& pts, bool enclosed = false) {
  pm::ScopedStage s("delaunay");
  try {
    return enclosed ? pm::delaunay_enclosed(pts.vertices) : pm::delaunay(pts.vertices);
  } catch (const pm::InputError& e) {
    throw pm::InputError(pm::quote(points) + ": " + e.what());
  }
}

// --improve's result: one info line and the "improve" stats object.
void report_improve(const pm::SurfaceImproveStats& is, int rounds, const char* valence_key) {
  pm::info("improved: " + std::to_string(is.flips) + " flips, " + std::to_string(is.moves) +
           " vertex moves; radius ratio min " + std::to_string(is.rr_min_before) + " -> " +
           std::to_string(is.rr_min_after) + ", mean " + std::to_string(is.rr_mean_before) + " -> " +
           std::to_string(is.rr_mean_after) + ", valence 6 " + std::to_string(is.valence6_before) + " -> " +
           std::to_string(is.valence6_after));
  pm::stats()["improve"] = {{"rounds", rounds}, {"flips", is.flips}, {"moves", is.moves},
                            {"rejected_moves", is.rejected_moves},
                            {"self_intersections", {is.self_intersections_before, is.self_intersections}},
                            {"frozen_vertices", is.frozen},
                            {"radius_ratio_min", {is.rr_min_before, is.rr_min_after}},
                            {"radius_ratio_mean", {is.rr_mean_before, is.rr_mean_after}},
                            {valence_key, {is.valence6_before, is.valence6_after}}};
}

std::string surface_path(const std::string& spec, int label) {
  const auto pct = spec.find("%d");
  if (pct != std::string::npos) return spec.substr(0, pct) + std::to_string(label) + spec.substr(pct + 2);
  return spec + "/material_" + std::to_string(label) + ".ply";
}

// Multi-material mode (--materials): interfaces, per-material surfaces, tets.
void run_materials(pm::Mesh pts, const std::string& points, const pm::MaterialOptions& mo,
                   const std::string& outside_opt, bool repair, int improve, const std::string& out,
                   const std::string& surfaces, const std::string& tets, pm::WorldFrame frame) {
  auto& st = pm::stats();
  const pm::MaterialSet ms = pm::load_materials(mo);
  pm::MaterialMeshParams mp;
  mp.repair = repair;
  if (outside_opt == "auto") {
    mp.outside_label = pm::auto_outside_label(ms);
  } else {
    try {
      std::size_t pos = 0;
      mp.outside_label = std::stoi(outside_opt, &pos);
      if (pos != outside_opt.size()) throw std::invalid_argument("");
    } catch (const std::exception&) {
      throw pm::UsageError("--outside \"" + outside_opt + "\" is not an integer label or auto");
    }
  }
  {
    pm::Box b;
    for (const auto& v : pts.vertices) b.extend(v);
    const std::size_t dup = drop_duplicates(pts, 1e-7 * std::max(pm::norm(b.size()), 1e-300));
    if (dup > 0) pm::warn(std::to_string(dup) + " duplicate particle(s) dropped (within 1e-7 of the bounding box diagonal)");
  }
  pm::TetMesh tm = delaunay_of(points, pts);
  pm::MaterialMeshes mm;
  {
    pm::ScopedStage s("label");
    mm = pm::mesh_materials(tm, ms, mp);
  }
  if (mm.interfaces.faces.empty())
    throw pm::InputError(pm::quote(points) + ": every tetrahedron has the same material (" +
                         std::to_string(tm.labels.empty() ? mp.outside_label : tm.labels[0]) +
                         "); expected particles sampling the interfaces between materials");
  copy_point_scalars(pts, mm.interfaces);
  const pm::MeshTopology it = pm::mesh_topology(mm.interfaces);
  if (it.boundary_edges > 0)
    pm::warn("the interface mesh has " + std::to_string(it.boundary_edges) + " boundary edges");
  for (int l : mm.nonmanifold_materials)
    pm::warn("the surface of material " + std::to_string(l) + " is not a closed manifold after the repair");
  const std::size_t buried = pts.vertices.size() - it.vertices;
  if (buried > 0)
    pm::warn(std::to_string(buried) + " particles are not on any interface (off the interfaces, or too close)");
  if (improve > 0) {
    pm::ScopedStage s("improve");
    pm::SurfaceImproveParams ip;
    ip.rounds = improve;
    const pm::SurfaceImproveStats is = pm::improve_interfaces(mm.interfaces, ms, ip);
    for (auto& [l, m] : mm.surfaces) m = pm::material_from_interfaces(mm.interfaces, l);
    report_improve(is, improve, "valence6_share_interface_vertices");
  }
  pm::write_mesh(mm.interfaces, out, {true, frame});
  pm::Json outputs = {out};
  pm::Json per = pm::Json::object();
  for (auto& [l, m] : mm.surfaces) {
    copy_point_scalars(pts, m);
    const pm::MeshTopology t = pm::mesh_topology(m);
    per[std::to_string(l)] = {{"tetrahedra", mm.tets_per_label[l]}, {"vertices", t.vertices}, {"faces", t.faces},
                              {"components", t.components}, {"genus", t.genus},
                              {"closed_manifold", t.closed_manifold()}};
    if (!surfaces.empty()) {
      const std::string path = surface_path(surfaces, l);
      pm::write_mesh(m, path, {true, frame});
      outputs.push_back(path);
    }
  }
  if (!tets.empty()) {
    pm::write_tet_mesh(pm::labelled_tets(tm, mp.outside_label), tets, {frame});
    outputs.push_back(tets);
  }
  pm::Json pairs = pm::Json::array();
  for (const auto& [a, b] : mm.pairs) pairs.push_back({a, b});
  pm::info(std::to_string(it.vertices) + " vertices, " + std::to_string(it.faces) + " interface triangles, " +
           std::to_string(mm.pairs.size()) + " material pairs, " + std::to_string(mm.surfaces.size()) +
           " material surfaces");
  st["parameters"] = {{"materials", mo.spec}, {"kernel", mo.kernel}, {"outside_label", mp.outside_label},
                      {"repair", repair}};
  st["outputs"] = outputs;
  st["counts"] = {{"particles", pts.vertices.size()}, {"tetrahedra", mm.label_stats.tets},
                  {"degenerate_tetrahedra", mm.label_stats.flat}, {"relabelled_for_manifold", mm.relabelled},
                  {"vertices", it.vertices}, {"faces", it.faces}, {"particles_not_on_interfaces", buried},
                  {"boundary_edges", it.boundary_edges}, {"nonmanifold_edges", it.nonmanifold_edges},
                  {"pairs", pairs}, {"materials", per}};
}

}  // namespace

int main(int argc, char** argv) {
  pm::Tool tool("tetlabel",
                "Triangulate surface particles: Delaunay-tetrahedralise them (TetGen), label each tetrahedron "
                "inside (F < iso) or outside by the field at its circumcentre, and write the faces between "
                "inside and outside as a closed, outward-oriented triangle mesh (PLY, VTK .vtp/.vtk, MEDIT, OBJ, OFF, "
                "STL by extension). With --materials (Chapter 6): label each tetrahedron by the material with the "
                "largest indicator at its circumcentre and write the interfaces between materials as one PLY "
                "with integer face properties label_a < label_b (normal from a into b) and pair, plus each "
                "material's closed surface (--material-surfaces), sharing its triangles with its neighbours. "
                "World units throughout.",
                "tetlabel points.ply -i brain_sdf.nrrd --iso 0 -o surface.ply --tets brain.mesh\n"
                "  tetlabel points.ply --materials labels.nrrd -o interfaces.ply --material-surfaces out/ "
                "--tets out/volume.mesh");
  std::string points, out, tets, inside = "auto", outside = "auto", surfaces;
  pm::MaterialOptions mo;
  bool repair = true;
  int improve = 0;
  pm::FieldOptions fo;
  tool.app.add_option("points", points, "Particles (PLY, OFF, OBJ, STL vertices), world units")->required();
  pm::add_field_options(tool.app, fo);
  tool.app.add_option("-o,--output", out, "Surface mesh to write (.ply .vtp .vtk .mesh .obj .off .stl; label_a/label_b kept by .ply .vtp .vtk and as MEDIT triangle references)")->required();
  tool.app.add_option("--inside", inside,
                      "Which side is the material: below (F < iso, distance fields), above (F > iso, masks, CT "
                      "intensities) or auto (the side the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  tool.app.add_flag("--repair,!--no-repair", repair,
                    "Relabel tetrahedra at pinched vertices so the surface is a manifold (default on)");
  tool.app.add_option("--improve", improve,
                      "Rounds of surface improvement after meshing (valence and quality edge flips, then "
                      "tangential smoothing with every vertex projected back onto F = iso, or with --materials "
                      "onto its interface f_a = f_b while junction curves and corners stay; topology kept, no "
                      "triangle folded, crossings checked). 0 = the plain Delaunay surface. --tets still writes "
                      "the Delaunay tetrahedra, whose boundary is the unimproved surface. Skipped, with a "
                      "warning, when the Delaunay surface is not a closed manifold")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  tool.app.add_option("--tets", tets, "Also write the inside tetrahedra, by extension: .mesh (MEDIT, material references and boundary triangles), .vtu or .vtk (VTK, cell array material), .msh (Gmsh 4.1, one physical group per material)");
  pm::add_material_options(tool.app, mo, false, "")
      ->excludes("--input")
      ->excludes("--implicit");
  tool.app.add_option("--outside", outside,
                      "With --materials: label outside the domain and beyond hull faces (auto = the material "
                      "at most domain corners, e.g. the background)")
      ->capture_default_str();
  tool.app.add_option("--material-surfaces", surfaces,
                      "With --materials: write each material's closed surface (all but the outside label) as "
                      "DIR/material_<label>.ply, or to a pattern with %d, e.g. \"out/m%d.off\"");
  pm::WorldFrame frame = pm::WorldFrame::lps;
  pm::add_frame_option(tool.app, frame);
  return tool.run(argc, argv, [&] {
    pm::check_output_path(out, pm::OutputKind::mesh, "--output");
    pm::check_output_path(tets, pm::OutputKind::tet_mesh, "--tets");
    if (surfaces.find("%d") != std::string::npos)
      pm::check_output_path(surface_path(surfaces, 0), pm::OutputKind::mesh, "--material-surfaces");
    auto& st = pm::stats();
    if (!mo.spec.empty()) {
      st["inputs"] = {points, mo.spec};
      // --kernel applies to the material volumes too; Catmull-Rom unless given.
      if (tool.app.count("--kernel") > 0) mo.kernel = fo.kernel;
      const pm::Mesh pts = pm::read_mesh(points);
      if (pts.vertices.size() < 4)
        throw pm::InputError(pm::quote(points) + ": " + std::to_string(pts.vertices.size()) +
                             " points; expected at least 4 particles");
      if (improve > 0 && !repair) throw pm::UsageError("--improve needs manifold surfaces: drop --no-repair");
      run_materials(pts, points, mo, outside, repair, improve, out, surfaces, tets, frame);
      return;
    }
    if (!surfaces.empty() || outside != "auto")
      throw pm::UsageError("--material-surfaces and --outside need --materials");
    if (improve > 0 && !repair) throw pm::UsageError("--improve needs a manifold surface: drop --no-repair");
    st["inputs"] = {points, fo.input.empty() ? fo.implicit : fo.input};
    const pm::LoadedField lf = pm::load_field(fo);
    const pm::Mesh pts = pm::read_mesh(points);
    if (pts.vertices.size() < 4)
      throw pm::InputError(pm::quote(points) + ": " + std::to_string(pts.vertices.size()) +
                           " points; expected at least 4 particles");
    pm::TetMesh tm = delaunay_of(points, pts, true);
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
    if (improve > 0 && !t.closed_manifold()) {
      // Flips and the crossing check need a closed manifold: keep the plain
      // surface (meshstats reports what is wrong with it) rather than fail.
      pm::warn("--improve skipped: the Delaunay surface is not a closed manifold (see above); the plain surface "
               "is written");
      st["improve"] = {{"rounds", improve}, {"skipped", "the Delaunay surface is not a closed manifold"}};
    } else if (improve > 0) {
      pm::ScopedStage s("improve");
      pm::SurfaceImproveParams ip;
      ip.rounds = improve;
      const pm::SurfaceImproveStats is = pm::improve_surface(surf, *lf.field, lf.iso, ip);
      report_improve(is, improve, "valence6_share");
    }
    pm::write_mesh(surf, out, {true, frame});
    if (!tets.empty()) pm::write_tet_mesh(pm::labelled_tets(tm, 0), tets, {frame});
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

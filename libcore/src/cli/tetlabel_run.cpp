#include "pm/cli/tetlabel_run.h"

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/base/stats.h"
#include "pm/cli/conform_tets.h"
#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/material_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/pipeline.h"
#include "pm/mesh/surface_improve.h"
#include "pm/mesh/tetlabel.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {
namespace {

// --improve's result: one info line and the "improve" stats object.
void report_improve(const pm::SurfaceImproveStats& is, int rounds, const char* valence_key) {
  pm::info("improved: " + std::to_string(is.flips) + " flips, " + std::to_string(is.moves) +
           " vertex moves; radius ratio min " + std::to_string(is.rr_min_before) + " -> " +
           std::to_string(is.rr_min_after) + ", mean " + std::to_string(is.rr_mean_before) + " -> " +
           std::to_string(is.rr_mean_after) + ", valence 6 " + std::to_string(is.valence6_before) + " -> " +
           std::to_string(is.valence6_after));
  pm::stats()["improve"] = {{"rounds", rounds},
                            {"flips", is.flips},
                            {"moves", is.moves},
                            {"rejected_moves", is.rejected_moves},
                            {"unfolded", is.unfolded},
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
  mp.outside_label = pm::parse_outside_label(outside_opt, ms);
  pm::MaterialStageParams sp;
  sp.outside_label = mp.outside_label;
  sp.repair = repair;
  sp.improve = improve;
  const pm::MaterialStageResult r = pm::mesh_materials_from_particles(std::move(pts), ms, sp, pm::quote(points));
  for (const auto& w : r.warnings) pm::warn(w);
  if (r.improve) report_improve(*r.improve, improve, "valence6_share_interface_vertices");
  const pm::MaterialMeshes& mm = r.meshes;
  const pm::TetMesh& tm = r.tets;
  const pm::MeshTopology& it = r.interface_topology;
  const std::size_t buried = r.buried;
  // The interfaces and each material's surface written (and the surfaces'
  // topology measured) side by side; an error is the first in this order.
  std::vector<std::pair<int, const pm::Mesh*>> each;
  for (const auto& [l, m] : mm.surfaces) each.emplace_back(l, &m);
  std::vector<pm::MeshTopology> topo(each.size());
  pm::parallel_tasks(each.size() + 1, [&](std::size_t i) {
    if (i == 0) {
      pm::write_mesh(mm.interfaces, out, {true, frame});
      return;
    }
    const auto& [l, m] = each[i - 1];
    topo[i - 1] = pm::mesh_topology(*m);
    if (!surfaces.empty()) pm::write_mesh(*m, surface_path(surfaces, l), {true, frame});
  });
  pm::Json outputs = {out};
  pm::Json per = pm::Json::object();
  for (std::size_t i = 0; i < each.size(); ++i) {
    const int l = each[i].first;
    const pm::MeshTopology& t = topo[i];
    per[std::to_string(l)] = {{"tetrahedra", mm.tets_per_label.count(l) ? mm.tets_per_label.at(l) : 0},
                              {"vertices", t.vertices},
                              {"faces", t.faces},
                              {"components", t.components},
                              {"genus", t.genus},
                              {"closed_manifold", t.closed_manifold()}};
    if (!surfaces.empty()) outputs.push_back(surface_path(surfaces, l));
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
  st["parameters"] = {
      {"materials", mo.spec}, {"kernel", mo.kernel}, {"outside_label", mp.outside_label}, {"repair", repair}};
  st["outputs"] = outputs;
  st["counts"] = {{"particles", r.particles},
                  {"tetrahedra", mm.label_stats.tets},
                  {"degenerate_tetrahedra", mm.label_stats.flat},
                  {"relabelled_for_manifold", mm.relabelled},
                  {"sliver_spikes_relabelled", mm.spikes},
                  {"vertices", it.vertices},
                  {"faces", it.faces},
                  {"particles_not_on_interfaces", buried},
                  {"boundary_edges", it.boundary_edges},
                  {"nonmanifold_edges", it.nonmanifold_edges},
                  {"pairs", pairs},
                  {"materials", per}};
}

}  // namespace

void add_tetlabel_options(CLI::App& app, TetLabelRun& cfg) {
  app.add_option("points", cfg.points, "Particles (PLY, OFF, OBJ, STL vertices), world units")->required();
  pm::add_field_options(app, cfg.fo);
  app.add_option("-o,--output", cfg.output,
                 "Surface mesh to write (.ply .vtp .vtk .mesh .obj .off .stl; label_a/label_b kept by .ply .vtp .vtk "
                 "and as MEDIT triangle references); required, except with --conform, which takes none");
  app.add_option("--inside", cfg.inside,
                 "Which side is the material: below (F < iso, distance fields), above (F > iso, masks, CT "
                 "intensities) or auto (the side the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  app.add_flag("--repair,!--no-repair", cfg.repair,
               "Relabel tetrahedra at pinched vertices so the surface is a manifold (default on)");
  app.add_option("--improve", cfg.improve,
                 "Rounds of surface improvement after meshing (valence and quality edge flips, then "
                 "tangential smoothing with every vertex projected back onto F = iso, or with --materials "
                 "onto its interface f_a = f_b while junction curves and corners stay; topology kept, no "
                 "triangle folded, crossings checked). 0 = the plain Delaunay surface. --tets still writes "
                 "the Delaunay tetrahedra, whose boundary is the unimproved surface. Skipped, with a "
                 "warning, when the Delaunay surface is not a closed manifold")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  app.add_option("--tets", cfg.tets_list,
                 "Also write the inside tetrahedra, by extension: .mesh (MEDIT, material references and boundary "
                 "triangles), .vtu or .vtk (VTK, cell array material), .msh (Gmsh 4.1, one physical group per material "
                 "and per interface); with --conform it may be given several times, one file per format")
      ->expected(1)
      ->take_all();
  pm::add_material_options(app, cfg.materials, false, "")->excludes("--input")->excludes("--implicit");
  app.add_option("--outside", cfg.outside,
                 "With --materials: label outside the domain and beyond hull faces (auto = the material "
                 "at most domain corners, e.g. the background)")
      ->capture_default_str();
  app.add_option("--material-surfaces", cfg.surfaces,
                 "With --materials: write each material's closed surface (all but the outside label) as "
                 "DIR/material_<label>.ply, or to a pattern with %d, e.g. \"out/m%d.off\"");
  pm::add_conform_options(app, cfg.cr);
  pm::add_frame_option(app, cfg.frame);
}

void run_tetlabel(TetLabelRun& cfg, const CommonFlags& flags, const CLI::App& app) {
  (void)flags;
  [[maybe_unused]] auto& points = cfg.points;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& tets = cfg.tets;
  [[maybe_unused]] auto& inside = cfg.inside;
  [[maybe_unused]] auto& outside = cfg.outside;
  [[maybe_unused]] auto& surfaces = cfg.surfaces;
  [[maybe_unused]] auto& tets_list = cfg.tets_list;
  [[maybe_unused]] auto& mo = cfg.materials;
  [[maybe_unused]] auto& repair = cfg.repair;
  [[maybe_unused]] auto& improve = cfg.improve;
  [[maybe_unused]] auto& fo = cfg.fo;
  [[maybe_unused]] auto& cr = cfg.cr;
  [[maybe_unused]] auto& frame = cfg.frame;
  if (!cr.surface.empty()) {
    if (!out.empty()) throw pm::UsageError("--conform writes only --tets: drop -o/--output");
    if (!surfaces.empty() || improve > 0 || app.count("--repair") + app.count("--no-repair") > 0)
      throw pm::UsageError("--material-surfaces, --improve and --repair do not apply to --conform");
    if (!mo.spec.empty() && app.count("--inside") > 0)
      throw pm::UsageError("--inside needs -i/--implicit, not --materials");
    if (mo.spec.empty() && outside != "auto") throw pm::UsageError("--outside needs --materials");
    cr.interior = points;
    cr.tets = tets_list;
    cr.field = fo;
    cr.inside = inside;
    cr.materials = mo;
    if (app.count("--kernel") > 0) cr.materials.kernel = fo.kernel;
    cr.outside = outside;
    cr.params.progress = pm::verbosity() != pm::Verbosity::quiet;
    cr.frame = frame;
    pm::run_conform(cr);
    return;
  }
  if (tets_list.size() > 1) throw pm::UsageError("--tets once, unless with --conform");
  if (!tets_list.empty()) tets = tets_list[0];
  for (const char* o : {"--min-dihedral", "--radius-edge", "--max-dihedral", "--rounds", "--optimise", "--no-optimise",
                        "--require", "--max-volume", "--boundary-clearance", "--exude-rounds", "--smooth"})
    if (app.count(o) > 0) throw pm::UsageError(std::string(o) + " needs --conform");
  if (out.empty()) throw pm::UsageError("--output is required (or --conform with --tets)");
  pm::check_output_path(out, pm::OutputKind::mesh, "--output");
  pm::check_output_path(tets, pm::OutputKind::tet_mesh, "--tets");
  if (surfaces.find("%d") != std::string::npos)
    pm::check_output_path(surface_path(surfaces, 0), pm::OutputKind::mesh, "--material-surfaces");
  auto& st = pm::stats();
  if (!mo.spec.empty()) {
    st["inputs"] = {points, mo.spec};
    // --kernel applies to the material volumes too; Catmull-Rom unless given.
    if (app.count("--kernel") > 0) mo.kernel = fo.kernel;
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
  pm::SurfaceMeshParams sp;
  sp.inside = inside == "auto"    ? pm::InsideSide::automatic
              : inside == "below" ? pm::InsideSide::below
                                  : pm::InsideSide::above;
  sp.repair = repair;
  sp.improve = improve;
  const pm::SurfaceMeshResult r = pm::mesh_surface_from_particles(pts, *lf.field, lf.iso, sp, pm::quote(points));
  st["parameters"] = {{"iso", lf.iso}, {"inside", r.below ? "below" : "above"}};
  for (const auto& w : r.warnings) pm::warn(w);
  const pm::MeshTopology& t = r.topology;
  if (improve > 0 && !r.improve)
    st["improve"] = {{"rounds", improve}, {"skipped", "the Delaunay surface is not a closed manifold"}};
  if (r.improve) report_improve(*r.improve, improve, "valence6_share");
  const pm::Mesh& surf = r.surface;
  const pm::TetMesh& tm = r.tets;
  const pm::TetLabelStats& ls = r.label_stats;
  const std::size_t relabelled = r.relabelled, buried = r.buried;
  pm::write_mesh(surf, out, {true, frame});
  if (!tets.empty()) pm::write_tet_mesh(pm::labelled_tets(tm, 0), tets, {frame});
  pm::info(std::to_string(t.vertices) + " vertices, " + std::to_string(t.faces) + " triangles, " +
           std::to_string(t.components) + " component(s), genus " + std::to_string(t.genus));
  st["outputs"] = tets.empty() ? pm::Json{out} : pm::Json{out, tets};
  st["counts"] = {{"particles", pts.vertices.size()},
                  {"tetrahedra", ls.tets},
                  {"degenerate_tetrahedra", ls.flat},
                  {"relabelled_for_manifold", relabelled},
                  {"vertices", t.vertices},
                  {"faces", t.faces},
                  {"particles_not_on_surface", buried},
                  {"components", t.components},
                  {"genus", t.genus},
                  {"boundary_edges", t.boundary_edges},
                  {"nonmanifold_edges", t.nonmanifold_edges},
                  {"nonmanifold_vertices", t.nonmanifold_vertices}};
}

}  // namespace pm

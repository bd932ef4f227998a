#include "pm/cli/baseline_run.h"

#include <cmath>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/frame_option.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/tet_mesh.h"
#include "pm/io/volume_io.h"
#include "pm/mesh/tet_quality.h"
#include "pm/mesh/tetlabel.h"

namespace pm {
namespace {

// --tets with --vertices: the facet size search scales as N^-0.4 (volumes
// graded from the surface), starting where the surface would hold a third
// of the vertices (brain, radius-edge 2: about 35% on the surface).
constexpr double kVolumeExponent = 0.4;
constexpr std::size_t kVolumeShare = 3;

// The size search's record in the stats, and a warning when it missed.
CgalMeshResult record(SizeSearchResult r, const SizeSearchParams& sp, Json& st) {
  if (sp.target > 0) {
    Json tries = Json::array();
    for (const auto& t : r.tries)
      tries.push_back({{"facet_size", t.facet_size}, {"vertices", t.vertices}, {"seconds", t.seconds}});
    st["size_search"] = tries;
    st["parameters"]["facet_size"] = r.facet_size;
    if (r.deviation > sp.tolerance)
      warn("vertex count " + std::to_string(r.best.surface.vertices.size()) + " is " +
           std::to_string(int(std::lround(100 * r.deviation))) + "% off the target " + std::to_string(sp.target));
  }
  st["counts"]["c3t3_vertices"] = r.best.c3t3_vertices;
  if (!r.best.steps.empty()) st["steps"] = to_json(r.best.steps);
  st["counts"]["parallel"] = r.best.parallel;
  st["seconds_final_run"] = r.best.seconds;
  return std::move(r.best);
}

}  // namespace

void add_baseline_options(CLI::App& app, BaselineRun& r) {
  app.add_option("mode", r.mode, "mc | cgal | cgal-labels")
      ->required()
      ->check(CLI::IsMember({"mc", "cgal", "cgal-labels"}));
  app.add_option("-i,--input", r.field.input, "Volume (.nrrd .nhdr .vdb .mha .nii .inr); cgal-labels: a label map")
      ->required();
  app.add_option("--iso", r.field.iso, "Isovalue (mc, cgal), in voxel value units")->capture_default_str();
  app.add_option("--inside", r.inside,
                 "Which side is the material (mc, cgal): below (F < iso), "
                 "above (F > iso) or auto (the side "
                 "the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  app.add_option("-o,--output", r.output,
                 "Surface mesh to write (.ply .vtp .vtk .mesh .obj .off .stl), "
                 "world units");
  app.add_option("--tets", r.tets,
                 "cgal modes: also mesh the volume and write its labelled tetrahedra (" + tet_mesh_extensions() +
                     "; material = 1 for an isosurface, the label for a label map)");
  app.add_option("--radius-edge", r.params.cell_radius_edge,
                 "with --tets: Mesh_3 cell_radius_edge_ratio (circumradius / "
                 "shortest edge), >= 2")
      ->capture_default_str();
  app.add_option("--cell-size", r.params.cell_size,
                 "with --tets: Mesh_3 cell_size (circumradius bound), world "
                 "units; 0 = none (cells grade "
                 "away from the surface)")
      ->capture_default_str();
  app.add_option("--outside", r.outside,
                 "cgal-labels: the label not meshed (the background), or auto: "
                 "the label at most of the "
                 "volume's 8 corners")
      ->capture_default_str();
  app.add_flag("--no-optimise", r.no_optimise, "with --tets: skip perturb_mesh_3 and exude_mesh_3");
  app.add_option("--optimise-seconds", r.params.optimise_seconds,
                 "with --tets: time limit of perturbation and of exudation, "
                 "each, s (0 = none)")
      ->capture_default_str();
  app.add_option("--vertices", r.vertices, "cgal modes: search the facet size so the mesh has about N vertices");
  app.add_option("--size", r.size, "cgal modes: Mesh_3 facet_size (and edge_size), world units");
  app.add_option("--distance", r.params.facet_distance,
                 "cgal modes: Mesh_3 facet_distance, world units (default size/4)");
  app.add_option("--angle", r.params.facet_angle, "cgal modes: Mesh_3 facet_angle, degrees")->capture_default_str();
  app.add_option("--vertex-tolerance", r.tolerance, "cgal modes with --vertices: accepted relative deviation")
      ->capture_default_str();
  app.add_option("--max-runs", r.max_runs, "cgal modes with --vertices: most Mesh_3 runs in the size search")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  add_frame_option(app, r.frame);
}

void run_baseline(BaselineRun& r, int threads, std::uint64_t seed) {
  const std::string& mode = r.mode;
  const std::string &out = r.output, &tets = r.tets, &inside = r.inside, &outside = r.outside;
  const FieldOptions& fo = r.field;
  const std::size_t vertices = r.vertices;
  const double size = r.size, tol = r.tolerance;
  const int max_runs = r.max_runs;
  const bool no_optimise = r.no_optimise;
  const WorldFrame frame = r.frame;
  CgalMeshParams& p = r.params;
  if (out.empty() && tets.empty()) throw UsageError("give -o SURFACE, --tets VOLUME, or both");
  if (!tets.empty() && mode == "mc")
    throw UsageError("mc: --tets is for the cgal modes; marching cubes makes surfaces only");
  if (!out.empty()) check_output_path(out, OutputKind::mesh, "--output");
  if (!tets.empty()) check_output_path(tets, OutputKind::tet_mesh, "--tets");
  auto& st = stats();
  st["inputs"] = {fo.input};
  st["parameters"] = {{"mode", mode}};
  if (mode != "mc" && (vertices > 0) == (size > 0))
    throw UsageError(mode + ": give exactly one of --vertices N or --size S (world units)");
  if (mode == "mc" && (vertices > 0 || size > 0))
    throw UsageError(
        "mc: --vertices and --size are for the cgal modes; "
        "marching cubes uses the voxel grid");
  Mesh m;
  LabelledTets volume;
  Stopwatch clock;
  if (outside != "auto") {
    if (mode != "cgal-labels") throw UsageError("--outside is for cgal-labels");
    std::size_t pos = 0;
    try {
      p.outside_label = std::stoi(outside, &pos);
    } catch (const std::exception&) {
      pos = 0;
    }
    if (pos != outside.size() || p.outside_label < 0)
      throw UsageError("--outside \"" + outside + "\": expected a non-negative integer label or auto");
  }
  p.volume = !tets.empty();
  p.optimise = !no_optimise;
  p.facet_size = size;
  p.threads = threads;
  p.seed = seed;
  if (mode == "cgal-labels") {
    Volume v;
    {
      ScopedStage s("read");
      v = read_volume(fo.input);
    }
    SizeSearchParams sp{vertices, size, tol, max_runs};
    if (p.volume) sp.exponent = kVolumeExponent;
    if (vertices > 0)
      sp.start_size =
          facet_size_for_vertices(label_interface_area(v, fo.input), p.volume ? vertices / kVolumeShare : vertices);
    ScopedStage s("cgal");
    CgalMeshResult r =
        record(cgal_size_search([&](const CgalMeshParams& q) { return cgal_labels(v, q); }, p, sp), sp, st);
    m = std::move(r.surface);
    volume = std::move(r.volume);
  } else {
    LoadedField lf;
    Volume v;
    {
      ScopedStage s("read");
      lf = load_field(fo);  // checks the isovalue against the value range
      v = read_volume(fo.input);
    }
    const bool below = inside == "auto" ? material_below_iso(*lf.field, lf.iso) : inside == "below";
    st["parameters"]["iso"] = lf.iso;
    st["parameters"]["inside"] = below ? "below" : "above";
    if (mode == "mc") {
      ScopedStage s("marching_cubes");
      m = marching_cubes_baseline(v, lf.iso, below);
    } else {
      SizeSearchParams sp{vertices, size, tol, max_runs};
      if (p.volume) sp.exponent = kVolumeExponent;
      if (vertices > 0)
        sp.start_size = facet_size_for_vertices(mesh_area(marching_cubes_baseline(v, lf.iso, below)),
                                                p.volume ? vertices / kVolumeShare : vertices);
      ScopedStage s("cgal");
      CgalMeshResult r =
          record(cgal_size_search([&](const CgalMeshParams& q) { return cgal_isosurface(v, lf.iso, below, q); }, p, sp),
                 sp, st);
      m = std::move(r.surface);
      volume = std::move(r.volume);
    }
  }
  const MeshTopology t = mesh_topology(m);
  if (!out.empty()) write_mesh(m, out, {true, frame});
  if (!tets.empty()) {
    write_tet_mesh(volume, tets, {frame});
    info(std::to_string(volume.vertices.size()) + " vertices, " + std::to_string(volume.tets.size()) +
         " tetrahedra -> " + tets);
    st["counts"]["tet_vertices"] = volume.vertices.size();
    st["counts"]["tetrahedra"] = volume.tets.size();
    st["quality"] = to_json(tet_quality(volume));
  }
  info(std::to_string(t.vertices) + " vertices, " + std::to_string(t.faces) + " triangles, " +
       std::to_string(t.components) + " component(s), genus " + std::to_string(t.genus));
  st["outputs"] = Json::array();
  for (const std::string& f : {out, tets})
    if (!f.empty()) st["outputs"].push_back(f);
  st["counts"]["vertices"] = t.vertices;
  st["counts"]["faces"] = t.faces;
  st["counts"]["components"] = t.components;
  st["counts"]["genus"] = t.genus;
  st["counts"]["boundary_edges"] = t.boundary_edges;
  st["counts"]["nonmanifold_edges"] = t.nonmanifold_edges;
  st["seconds_total"] = clock.seconds();
}

}  // namespace pm

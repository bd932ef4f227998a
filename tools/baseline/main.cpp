// baseline: the meshes we compare against. Marching cubes (OpenVDB) and CGAL
// Mesh_3 on the same isosurface, and CGAL Mesh_3 on a label map.
#include <cmath>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/volume_io.h"
#include "pm/baseline/baseline.h"
#include "pm/mesh/tetlabel.h"
#include "pm/cli/frame_option.h"
#include "pm/io/output_path.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/tet_quality.h"

namespace {

// --tets with --vertices: the facet size search scales as N^-0.4 (volumes
// graded from the surface), starting where the surface would hold a third
// of the vertices (brain, radius-edge 2: about 35% on the surface).
constexpr double kVolumeExponent = 0.4;
constexpr std::size_t kVolumeShare = 3;

// The size search's record in the stats, and a warning when it missed.
pm::CgalMeshResult record(pm::SizeSearchResult r, const pm::SizeSearchParams& sp, pm::Json& st) {
  if (sp.target > 0) {
    pm::Json tries = pm::Json::array();
    for (const auto& t : r.tries)
      tries.push_back({{"facet_size", t.facet_size}, {"vertices", t.vertices}, {"seconds", t.seconds}});
    st["size_search"] = tries;
    st["parameters"]["facet_size"] = r.facet_size;
    if (r.deviation > sp.tolerance)
      pm::warn("vertex count " + std::to_string(r.best.surface.vertices.size()) + " is " +
               std::to_string(int(std::lround(100 * r.deviation))) + "% off the target " + std::to_string(sp.target));
  }
  st["counts"]["c3t3_vertices"] = r.best.c3t3_vertices;
  if (!r.best.steps.empty()) st["steps"] = pm::to_json(r.best.steps);
  st["counts"]["parallel"] = r.best.parallel;
  st["seconds_final_run"] = r.best.seconds;
  return std::move(r.best);
}

}  // namespace

int main(int argc, char** argv) {
  pm::Tool tool("baseline",
                "Baseline meshes to compare particle meshes with, on the same volume (world units from its header). "
                "mc: marching cubes of F = iso (OpenVDB volumeToMesh, adaptivity 0, trilinear). cgal: CGAL Mesh_3 "
                "surface mesh of the image isosurface (facet angle 30, facet distance = size/4, manifold), with the "
                "facet size given or searched so the vertex count matches --vertices. cgal-labels: CGAL Mesh_3 on a "
                "label map with the lines where three labels meet protected and the outside label (--outside) not "
                "meshed; writes every interface with face properties label_a < label_b. Outputs are closed triangle meshes (.ply .obj .off .stl). "
                "With --tets, the cgal modes mesh the volume too (cell radius-edge ratio, optional cell size), then "
                "run CGAL's sliver perturbation and exudation, and write the labelled tetrahedra; --vertices then "
                "counts the tetrahedra's vertices.",
                "baseline cgal -i brain_sdf.nrrd --iso 0 --vertices 100000 -o cgal.ply --stats cgal.json\n"
                "  baseline cgal-labels -i labels.nrrd --vertices 200000 --tets cgal_volume.mesh --stats cgal.json");
  std::string mode, out, inside = "auto";
  pm::FieldOptions fo;
  std::size_t vertices = 0;
  double size = 0, distance = 0, angle = 30, tol = 0.1;
  int max_runs = 5;
  tool.app.add_option("mode", mode, "mc | cgal | cgal-labels")->required()->check(
      CLI::IsMember({"mc", "cgal", "cgal-labels"}));
  tool.app.add_option("-i,--input", fo.input, "Volume (.nrrd .nhdr .vdb .mha .nii .inr); cgal-labels: a label map")
      ->required();
  tool.app.add_option("--iso", fo.iso, "Isovalue (mc, cgal), in voxel value units")->capture_default_str();
  tool.app.add_option("--inside", inside,
                      "Which side is the material (mc, cgal): below (F < iso), above (F > iso) or auto (the side "
                      "the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  std::string tets;
  pm::CgalMeshParams p;
  bool no_optimise = false;
  tool.app.add_option("-o,--output", out, "Surface mesh to write (.ply .vtp .vtk .mesh .obj .off .stl), world units");
  tool.app.add_option("--tets", tets,
                      "cgal modes: also mesh the volume and write its labelled tetrahedra (" +
                          pm::tet_mesh_extensions() + "; material = 1 for an isosurface, the label for a label map)");
  tool.app.add_option("--radius-edge", p.cell_radius_edge,
                      "with --tets: Mesh_3 cell_radius_edge_ratio (circumradius / shortest edge), >= 2")
      ->capture_default_str();
  tool.app.add_option("--cell-size", p.cell_size,
                      "with --tets: Mesh_3 cell_size (circumradius bound), world units; 0 = none (cells grade "
                      "away from the surface)")
      ->capture_default_str();
  std::string outside = "auto";
  tool.app.add_option("--outside", outside,
                      "cgal-labels: the label not meshed (the background), or auto: the label at most of the "
                      "volume's 8 corners")
      ->capture_default_str();
  tool.app.add_flag("--no-optimise", no_optimise, "with --tets: skip perturb_mesh_3 and exude_mesh_3");
  tool.app.add_option("--optimise-seconds", p.optimise_seconds,
                      "with --tets: time limit of perturbation and of exudation, each, s (0 = none)")
      ->capture_default_str();
  tool.app.add_option("--vertices", vertices, "cgal modes: search the facet size so the mesh has about N vertices");
  tool.app.add_option("--size", size, "cgal modes: Mesh_3 facet_size (and edge_size), world units");
  tool.app.add_option("--distance", distance, "cgal modes: Mesh_3 facet_distance, world units (default size/4)");
  tool.app.add_option("--angle", angle, "cgal modes: Mesh_3 facet_angle, degrees")->capture_default_str();
  tool.app.add_option("--vertex-tolerance", tol, "cgal modes with --vertices: accepted relative deviation")
      ->capture_default_str();
  tool.app.add_option("--max-runs", max_runs, "cgal modes with --vertices: most Mesh_3 runs in the size search")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  pm::WorldFrame frame = pm::WorldFrame::lps;
  pm::add_frame_option(tool.app, frame);
  return tool.run(argc, argv, [&] {
    if (out.empty() && tets.empty()) throw pm::UsageError("give -o SURFACE, --tets VOLUME, or both");
    if (!tets.empty() && mode == "mc")
      throw pm::UsageError("mc: --tets is for the cgal modes; marching cubes makes surfaces only");
    if (!out.empty()) pm::check_output_path(out, pm::OutputKind::mesh, "--output");
    if (!tets.empty()) pm::check_output_path(tets, pm::OutputKind::tet_mesh, "--tets");
    auto& st = pm::stats();
    st["inputs"] = {fo.input};
    st["parameters"] = {{"mode", mode}};
    if (mode != "mc" && (vertices > 0) == (size > 0))
      throw pm::UsageError(mode + ": give exactly one of --vertices N or --size S (world units)");
    if (mode == "mc" && (vertices > 0 || size > 0))
      throw pm::UsageError("mc: --vertices and --size are for the cgal modes; marching cubes uses the voxel grid");
    pm::Mesh m;
    pm::LabelledTets volume;
    pm::Stopwatch clock;
    if (outside != "auto") {
      if (mode != "cgal-labels") throw pm::UsageError("--outside is for cgal-labels");
      std::size_t pos = 0;
      try {
        p.outside_label = std::stoi(outside, &pos);
      } catch (const std::exception&) {
        pos = 0;
      }
      if (pos != outside.size() || p.outside_label < 0)
        throw pm::UsageError("--outside \"" + outside + "\": expected a non-negative integer label or auto");
    }
    p.volume = !tets.empty();
    p.optimise = !no_optimise;
    p.facet_size = size;
    p.facet_distance = distance;
    p.facet_angle = angle;
    p.threads = tool.flags.threads;
    p.seed = tool.flags.seed;
    if (mode == "cgal-labels") {
      pm::Volume v;
      {
        pm::ScopedStage s("read");
        v = pm::read_volume(fo.input);
      }
      pm::SizeSearchParams sp{vertices, size, tol, max_runs};
      if (p.volume) sp.exponent = kVolumeExponent;
      if (vertices > 0)
        sp.start_size = pm::facet_size_for_vertices(pm::label_interface_area(v, fo.input),
                                                    p.volume ? vertices / kVolumeShare : vertices);
      pm::ScopedStage s("cgal");
      pm::CgalMeshResult r =
          record(pm::cgal_size_search([&](const pm::CgalMeshParams& q) { return pm::cgal_labels(v, q); }, p, sp), sp,
                 st);
      m = std::move(r.surface);
      volume = std::move(r.volume);
    } else {
      pm::LoadedField lf;
      pm::Volume v;
      {
        pm::ScopedStage s("read");
        lf = pm::load_field(fo);  // checks the isovalue against the value range
        v = pm::read_volume(fo.input);
      }
      const bool below = inside == "auto" ? pm::material_below_iso(*lf.field, lf.iso) : inside == "below";
      st["parameters"]["iso"] = lf.iso;
      st["parameters"]["inside"] = below ? "below" : "above";
      if (mode == "mc") {
        pm::ScopedStage s("marching_cubes");
        m = pm::marching_cubes_baseline(v, lf.iso, below);
      } else {
        pm::SizeSearchParams sp{vertices, size, tol, max_runs};
        if (p.volume) sp.exponent = kVolumeExponent;
        if (vertices > 0)
          sp.start_size = pm::facet_size_for_vertices(pm::mesh_area(pm::marching_cubes_baseline(v, lf.iso, below)),
                                                      p.volume ? vertices / kVolumeShare : vertices);
        pm::ScopedStage s("cgal");
        pm::CgalMeshResult r = record(
            pm::cgal_size_search([&](const pm::CgalMeshParams& q) { return pm::cgal_isosurface(v, lf.iso, below, q); },
                                 p, sp),
            sp, st);
        m = std::move(r.surface);
        volume = std::move(r.volume);
      }
    }
    const pm::MeshTopology t = pm::mesh_topology(m);
    if (!out.empty()) pm::write_mesh(m, out, {true, frame});
    if (!tets.empty()) {
      pm::write_tet_mesh(volume, tets, {frame});
      pm::info(std::to_string(volume.vertices.size()) + " vertices, " + std::to_string(volume.tets.size()) +
               " tetrahedra -> " + tets);
      st["counts"]["tet_vertices"] = volume.vertices.size();
      st["counts"]["tetrahedra"] = volume.tets.size();
      st["quality"] = pm::to_json(pm::tet_quality(volume));
    }
    pm::info(std::to_string(t.vertices) + " vertices, " + std::to_string(t.faces) + " triangles, " +
             std::to_string(t.components) + " component(s), genus " + std::to_string(t.genus));
    st["outputs"] = pm::Json::array();
    for (const std::string& f : {out, tets})
      if (!f.empty()) st["outputs"].push_back(f);
    st["counts"]["vertices"] = t.vertices;
    st["counts"]["faces"] = t.faces;
    st["counts"]["components"] = t.components;
    st["counts"]["genus"] = t.genus;
    st["counts"]["boundary_edges"] = t.boundary_edges;
    st["counts"]["nonmanifold_edges"] = t.nonmanifold_edges;
    st["seconds_total"] = clock.seconds();
  });
}

#include "pm/cli/meshstats_run.h"

#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/poly_mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/io/volume_io.h"
#include "pm/mesh/coverage.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/quad_mesh.h"
#include "pm/mesh/tet_quality.h"

namespace pm {
namespace {
void print_table(const pm::MeshQuality& q) {
  if (pm::verbosity() == pm::Verbosity::quiet) return;
  const auto& t = q.topology;
  std::fprintf(stderr, "  vertices %zu  triangles %zu  components %zu  genus %ld\n", q.vertices, q.faces, t.components,
               t.genus);
  std::fprintf(stderr, "  watertight %s  manifold %s  self-intersecting pairs %s\n",
               t.boundary_edges == 0 ? "yes" : "NO",
               t.nonmanifold_edges == 0 && t.nonmanifold_vertices == 0 ? "yes" : "NO",
               q.self_intersecting_pairs < 0 ? "not tested" : std::to_string(q.self_intersecting_pairs).c_str());
  std::fprintf(stderr, "  radius ratio min %.3f mean %.3f   angles %.1f..%.1f deg\n", q.rr_min, q.rr_mean,
               q.min_angle_deg, q.max_angle_deg);
  std::fprintf(stderr, "  valence 6: %.1f%%   <5 or >7: %.2f%%   creases > 20 deg: %.2f%% of %zu interior edges\n",
               100 * q.valence6_share, 100 * q.valence_outside_5_7_share, 100 * q.crease_share_20, q.interior_edges);
  if (q.has_sizing)
    std::fprintf(stderr, "  edge/h mean %.3f max %.3f  edges <= 2h: %.4f%%\n", q.edge_h_mean, q.edge_h_max,
                 100 * q.edge_le_2h_share);
  if (q.has_field)
    std::fprintf(
        stderr,
        "  distance to surface: vertices max %.3g mean %.3g, centroids max %.3g mean %.3g (%zu not projected)\n",
        q.dist_vertex_max, q.dist_vertex_mean, q.dist_centroid_max, q.dist_centroid_mean, q.dist_failed);
}
void print_interface_table(const pm::InterfaceQuality& q) {
  if (pm::verbosity() == pm::Verbosity::quiet) return;
  std::fprintf(stderr, "  interfaces: %zu vertices  %zu triangles  %zu material pairs  %zu materials\n",
               q.overall.vertices, q.overall.faces, q.pairs.size(), q.materials.size());
  std::fprintf(stderr, "  edges %zu  boundary %zu  junction-curve %zu  bad %zu  self-separating faces %zu\n", q.edges,
               q.boundary_edges, q.junction_edges, q.bad_edges, q.self_faces);
  std::fprintf(stderr, "  overall: radius ratio min %.3f mean %.3f   valence 6: %.1f%%   creases > 20 deg: %.2f%%\n",
               q.overall.rr_min, q.overall.rr_mean, 100 * q.overall.valence6_share, 100 * q.overall.crease_share_20);
  for (const auto& [pr, c] : q.pair_creases)
    std::fprintf(stderr, "    interface %d-%d: creases > 20 deg %.2f%% of %zu interior edges\n", pr.first, pr.second,
                 100 * c.share(), c.interior_edges);
  std::fprintf(stderr, "  %8s %8s %8s %7s %7s %6s %8s %9s %6s\n", "material", "vertices", "faces", "rr_min", "rr_mean",
               "val6%", "closed", "manifold", "selfX");
  for (const auto& [l, mq] : q.materials) {
    const auto& t = mq.topology;
    std::fprintf(stderr, "  %8d %8zu %8zu %7.3f %7.3f %6.1f %8s %9s %6s\n", l, mq.vertices, mq.faces, mq.rr_min,
                 mq.rr_mean, 100 * mq.valence6_share, t.boundary_edges == 0 ? "yes" : "NO",
                 t.nonmanifold_edges == 0 && t.nonmanifold_vertices == 0 ? "yes" : "NO",
                 mq.self_intersecting_pairs < 0 ? "-" : std::to_string(mq.self_intersecting_pairs).c_str());
  }
}
}  // namespace

void add_meshstats_options(CLI::App& app, MeshStatsRun& cfg) {
  app.add_option("mesh", cfg.mesh_path,
                 "Triangle mesh (.ply .vtk .mesh .obj .off .stl) or tetrahedral mesh (.mesh .vtu .vtk .msh)")
      ->required();
  pm::add_field_options(app, cfg.fo);
  app.add_option("--sizing", cfg.sizing_path, "Sizing field volume h (world units) for the edge/h check");
  app.add_option("-o,--output", cfg.output, "Write the report as JSON ('-' = stdout)");
  app.add_option("--require", cfg.require,
                 "Comma-separated checks, e.g. rr_min>=0.3,rr_mean>=0.94,valence6>=0.65,"
                 "valence_outside_5_7<=0.01,edge_le_2h>=0.9999,crease_share_20<=0.03,watertight,manifold,"
                 "no_self_intersections,genus=0; tetrahedra: dihedral_min>=12,dihedral_max<=160,share_25_140>=0.99,"
                 "rr_mean>=0.8,share_under_10<=0,positive,boundary_manifold,triangles_match");
  app.add_flag("--no-self-intersections", cfg.no_self, "Skip the (slower) self-intersection test");
  app.add_flag("--single", cfg.single, "Measure an interface mesh (label_a/label_b faces) as one plain mesh");
  app.add_option("--seeds", cfg.seeds_path,
                 "Marching-cubes seeds of the same surface (mcinit output, vertex property 'component'): "
                 "fail (exit 1) when a component of the isosurface has no mesh vertex near it");
  app.add_option("--min-component-seeds", cfg.min_seeds,
                 "With --seeds: components with fewer seeds than this (smaller than a few voxels) only warn")
      ->capture_default_str();
}

void run_meshstats(MeshStatsRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& mesh_path = cfg.mesh_path;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& sizing_path = cfg.sizing_path;
  [[maybe_unused]] auto& require = cfg.require;
  [[maybe_unused]] auto& no_self = cfg.no_self;
  [[maybe_unused]] auto& single = cfg.single;
  [[maybe_unused]] auto& seeds_path = cfg.seeds_path;
  [[maybe_unused]] auto& min_seeds = cfg.min_seeds;
  [[maybe_unused]] auto& fo = cfg.fo;
  pm::check_output_path(out, pm::OutputKind::json, "--output");
  auto& st = pm::stats();
  st["inputs"] = {mesh_path};
  auto write_report = [&](const pm::Json& j) {
    if (out == "-") {
      std::cout << j.dump(2) << "\n";
    } else if (!out.empty()) {
      pm::write_atomically(out, [&](const std::string& tmp) {
        std::ofstream f(tmp);
        f << j.dump(2) << "\n";
        if (!f) throw pm::IoError(pm::quote(out) + ": cannot write");
      });
    }
  };
  if (pm::is_tet_mesh_file(mesh_path)) {
    pm::check_tet_requirements(pm::TetQuality{}, require);  // usage errors before the work
    pm::TetQuality tq;
    {
      pm::ScopedStage s("quality");
      tq = pm::tet_quality(pm::read_tet_mesh(mesh_path));
    }
    const pm::Json j = pm::to_json(tq);
    st["quality"] = j;
    if (pm::verbosity() != pm::Verbosity::quiet) std::fputs(pm::format_table(tq).c_str(), stderr);
    write_report(j);
    const auto failed = pm::check_tet_requirements(tq, require);
    if (!failed.empty()) {
      std::string msg = pm::quote(mesh_path) + ": " + std::to_string(failed.size()) + " requirement(s) not met:";
      for (const auto& f : failed) msg += " " + f;
      throw pm::CheckFailed(msg);
    }
    return;
  }
  const pm::Mesh m = pm::read_mesh(mesh_path);
  if (m.faces.empty()) throw pm::InputError(pm::quote(mesh_path) + ": no faces; expected a triangle mesh");
  pm::MeshQualityParams p;
  pm::LoadedField lf;
  if (!fo.input.empty() || !fo.implicit.empty()) {
    lf = pm::load_field(fo);
    p.field = lf.field.get();
    p.iso = lf.iso;
  }
  std::unique_ptr<pm::SizingField> sizing;
  if (!sizing_path.empty()) {
    sizing = std::make_unique<pm::SizingField>(pm::read_volume(sizing_path), sizing_path);
    p.sizing = sizing.get();
  }
  p.self_intersections = !no_self;
  if (pm::is_interface_mesh(m) && !single) {
    pm::InterfaceQuality iq;
    {
      pm::ScopedStage s("quality");
      iq = pm::interface_quality(m, p);
    }
    const pm::Json j = pm::to_json(iq);
    st["quality"] = j;
    print_interface_table(iq);
    write_report(j);
    if (!require.empty()) {
      const auto failed = pm::check_interface_requirements(iq, require);
      if (!failed.empty()) {
        std::string msg = pm::quote(mesh_path) + ": " + std::to_string(failed.size()) + " requirement(s) not met:";
        for (const auto& f : failed) msg += " " + f + ";";
        msg.pop_back();
        throw pm::CheckFailed(msg);
      }
    }
    return;
  }
  pm::MeshQuality q;
  {
    pm::ScopedStage s("quality");
    q = pm::mesh_quality(m, p);
  }
  pm::Json j = pm::to_json(q);
  // A polygon mesh (quadmesh's output): the quad figures too, from the file with its quads kept; the
  // figures above are of its fan triangulation (topology, distance to the isosurface, intersections).
  std::unique_ptr<pm::QuadQuality> quads;
  if (pm::is_poly_mesh_path(mesh_path)) {
    const pm::PolyMesh pmesh = pm::read_poly_mesh(mesh_path);
    if (pmesh.quad_count() > 0) {
      quads = std::make_unique<pm::QuadQuality>(pm::quad_quality(pmesh));
      j["polygons"] = pm::to_json(*quads);
    }
  }
  std::string missing;
  if (!seeds_path.empty()) {
    const pm::Mesh seeds = pm::read_mesh(seeds_path);
    std::vector<pm::ComponentCoverage> cov;
    try {
      cov = pm::component_coverage(seeds, m.vertices);
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(seeds_path) + ": " + e.what());
    }
    std::size_t n_missing = 0, n_small = 0;
    for (const auto& c : cov) {
      if (c.points > 0) continue;
      const pm::Vec3 mid = (c.bounds.lo + c.bounds.hi) * 0.5;
      char where[160];
      std::snprintf(where, sizeof where, "component %d (%zu seeds, around (%.4g, %.4g, %.4g))", c.component, c.seeds,
                    mid.x, mid.y, mid.z);
      if (c.seeds < min_seeds) {
        ++n_small;
        pm::warn(std::string("small surface ") + where + " has no mesh vertex");
      } else {
        if (n_missing < 5) missing += std::string(n_missing ? "; " : "") + where;
        ++n_missing;
      }
    }
    j["surface_components"] = cov.size();
    j["unsampled_components"] = n_missing;
    j["unsampled_small_components"] = n_small;
    if (n_missing > 5) missing += "; and " + std::to_string(n_missing - 5) + " more";
  }
  st["quality"] = j;
  print_table(q);
  if (quads && pm::verbosity() != pm::Verbosity::quiet)
    std::fprintf(stderr,
                 "  polygons: %zu quads, %zu triangles (%.2f%% quads), corners %.1f..%.1f deg, %.2f%% in 90 +- 20, "
                 "valence 4 %.2f%% (%zu irregular), scaled Jacobian min %.3f mean %.3f\n",
                 quads->quads, quads->triangles, 100 * quads->quad_share(), quads->corner_min, quads->corner_max,
                 100 * quads->corner_share_70_110(), 100 * quads->valence4_share(), quads->irregular,
                 quads->jacobian_min, quads->jacobian_mean);
  write_report(j);
  if (!missing.empty())
    throw pm::InputError(pm::quote(mesh_path) +
                         ": the mesh misses components of the isosurface found by the "
                         "marching-cubes seeds " +
                         pm::quote(seeds_path) + ": " + missing +
                         "; expected particles on every component (seed the particles with these seeds)");
  if (!require.empty()) {
    const auto failed = pm::check_requirements(q, require, quads.get());
    if (!failed.empty()) {
      std::string msg = pm::quote(mesh_path) + ": " + std::to_string(failed.size()) + " requirement(s) not met:";
      for (const auto& f : failed) msg += " " + f;
      throw pm::CheckFailed(msg);
    }
  }
}

}  // namespace pm

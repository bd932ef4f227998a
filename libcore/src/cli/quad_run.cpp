#include "pm/cli/quad_run.h"

#include <array>
#include <cmath>
#include <map>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/poly_mesh.h"

namespace pm {
namespace {

std::vector<int> types_of(const Mesh& s, const QuadRun& r) {
  std::vector<int> type(s.vertices.size(), -1);
  auto check = [&](double t, const std::string& file, std::size_t i) {
    if (t != 0 && t != 1)
      throw InputError(quote(file) + ": vertex " + std::to_string(i) + " has type " + format_number(t) +
                       "; expected 0 or 1 (particles --quads)");
    return int(t);
  };
  if (r.types.empty()) {
    const auto it = s.vertex_scalars.find("type");
    if (it == s.vertex_scalars.end())
      throw InputError(quote(r.surface) + " has no vertex property `type`; expected the mesh of `particles "
                       "--quads` samples, or --types POINTS with the typed particles");
    for (std::size_t i = 0; i < type.size(); ++i) type[i] = check(it->second[i], r.surface, i);
    return type;
  }
  const Mesh pts = read_mesh(r.types);
  const auto it = pts.vertex_scalars.find("type");
  if (it == pts.vertex_scalars.end())
    throw InputError(quote(r.types) + " has no vertex property `type`; expected the output of particles --quads");
  std::map<std::array<double, 3>, int> at;
  for (std::size_t i = 0; i < pts.vertices.size(); ++i)
    at[{pts.vertices[i].x, pts.vertices[i].y, pts.vertices[i].z}] = check(it->second[i], r.types, i);
  std::size_t missing = 0, first = 0;
  for (std::size_t i = 0; i < type.size(); ++i) {
    const auto f = at.find({s.vertices[i].x, s.vertices[i].y, s.vertices[i].z});
    if (f == at.end()) {
      if (!missing++) first = i;
    } else {
      type[i] = f->second;
    }
  }
  if (missing)
    throw InputError(quote(r.surface) + ": " + std::to_string(missing) + " of " + std::to_string(type.size()) +
                     " vertices (e.g. vertex " + std::to_string(first) + ") are at no particle of " + quote(r.types) +
                     "; expected the surface meshed from those particles without moving them (tetlabel "
                     "--improve 0)");
  return type;
}

}  // namespace

void add_quad_options(CLI::App& app, QuadRun& r) {
  app.add_option("surface", r.surface, "Triangle mesh of two-type particles (.ply .vtk .mesh .obj .off .stl)")
      ->required();
  app.add_option("-o,--output", r.output, "Quad-dominant mesh to write, quads kept (" + poly_mesh_extensions() + ")")
      ->required();
  app.add_option("--types", r.types,
                 "Typed particles (particles --quads output) when the surface has no vertex property `type`; "
                 "matched by position");
  app.add_option("--max-corner-deviation", r.params.max_corner_deviation,
                 "A quad is made only when every corner angle is within this of 90 degrees, degrees")
      ->check(CLI::Range(1.0, 89.0))
      ->capture_default_str();
  app.add_option("--max-fold", r.params.max_fold,
                 "... and the two triangles' normals differ by at most this, degrees")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  app.add_flag("--pair-leftovers,!--no-pair-leftovers", r.params.pair_leftovers,
               "Pair the triangles left after dropping like edges across unlike edges too")
      ->capture_default_str();
  app.add_flag("--ascii", r.ascii, "ASCII PLY instead of binary");
  add_field_options(app, r.field);
  app.add_option("--smooth", r.smooth.passes,
                 "With the surface's field (-i VOLUME --iso C, or --implicit): passes of corner-angle smoothing, "
                 "each vertex moved in its tangent plane and projected back onto F = iso (0 = off)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_flag("--gmsh", r.gmsh,
               "The baseline: recombine the same triangles with Gmsh instead (no types needed; Blossom matching, "
               "the input's vertices kept)");
  app.add_option("--gmsh-algorithm", r.gmsh_params.algorithm,
                 "with --gmsh: Gmsh's Mesh.RecombinationAlgorithm (0 simple, 1 Blossom; 2 and 3, the full-quad "
                 "variants, subdivide and change the vertices)")
      ->check(CLI::Range(0, 3))
      ->capture_default_str();
  app.add_option("--gmsh-optimize-topology", r.gmsh_params.optimize_topology,
                 "with --gmsh: Gmsh's Mesh.RecombineOptimizeTopology passes (> 0 adds, removes and moves vertices)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
}

void check_quad_options(const QuadRun& r) {
  if (r.gmsh && !r.types.empty()) throw UsageError("--gmsh recombines without types; drop --types");
  const std::string e = file_extension(r.output);
  if (e == ".stl" || e == ".mesh" || e == ".vtp" || e == ".vtk")
    throw UsageError("--output " + quote(r.output) + ": " + e + " is written with triangles only; expected " +
                     poly_mesh_extensions() + " to keep the quads");
  check_output_path(r.output, OutputKind::poly_mesh, "--output");
}

void run_quads(const QuadRun& r) {
  check_quad_options(r);
  Mesh s = read_mesh(r.surface);
  if (s.faces.empty()) throw InputError(quote(r.surface) + " has no triangles; expected a surface mesh");
  for (std::size_t i = 0; i < s.vertices.size(); ++i)
    if (!is_finite(s.vertices[i]))
      throw InputError(quote(r.surface) + ": vertex " + std::to_string(i) + " is not finite; expected finite "
                       "coordinates");
  LoadedField lf;
  const bool have_field = !r.field.input.empty() || !r.field.implicit.empty();
  if (have_field) {
    ScopedStage stage("field");
    lf = load_field(r.field);
  }
  QuadResult q;
  QuadQuality qq, raw;
  QuadSmoothStats sm;
  GmshRecombineResult g;
  if (r.gmsh) {
    ScopedStage stage("gmsh");
    g = gmsh_recombine(s, r.gmsh_params);
    q.mesh = std::move(g.mesh);
    qq = quad_quality(q.mesh);
  } else {
    const std::vector<int> type = types_of(s, r);
    ScopedStage stage("quads");
    q = quad_dominant(s, type, r.params);
    qq = quad_quality(q.mesh);
  }
  raw = qq;
  if (have_field && r.smooth.passes > 0) {
    ScopedStage stage("smooth");
    sm = smooth_quads(q.mesh, *lf.field, lf.iso, r.smooth);
    qq = quad_quality(q.mesh);
  } else if (!have_field) {
    info("no field given (-i VOLUME --iso C or --implicit): the quads are not smoothed");
  }
  {
    ScopedStage stage("write");
    write_poly_mesh(q.mesh, r.output, r.frame, !r.ascii);
  }
  auto& st = stats();
  st["inputs"] = {r.surface, r.types};
  st["outputs"] = {r.output};
  if (r.gmsh) {
    st["inputs"] = {r.surface};
    st["parameters"] = {{"method", "gmsh"},
                        {"gmsh_version", g.gmsh_version},
                        {"recombination_algorithm", r.gmsh_params.algorithm},
                        {"optimize_topology", r.gmsh_params.optimize_topology}};
    st["counts"] = {{"triangles_in", s.faces.size()},
                    {"vertices_in", g.input_vertices},
                    {"vertices_out", q.mesh.vertices.size()}};
    st["seconds_gmsh"] = g.seconds;
  } else {
    st["parameters"] = {{"method", "types"},
                        {"max_corner_deviation", r.params.max_corner_deviation},
                        {"max_fold", r.params.max_fold},
                        {"pair_leftovers", r.params.pair_leftovers}};
    st["counts"] = {{"triangles_in", s.faces.size()},   {"like_edges", q.like_edges},
                    {"like_merges", q.like_merges},     {"leftover_merges", q.leftover_merges}, {"augmenting_paths", q.augmented},
                    {"triangles_left", q.triangles_left}};
  }
  st["quality"] = to_json(qq);
  if (have_field) {
    st["parameters"]["field"] = lf.field->describe();
    st["parameters"]["iso"] = lf.iso;
    st["parameters"]["smooth_passes"] = r.smooth.passes;
    st["quality_unsmoothed"] = to_json(raw);
    st["smoothing"] = {{"moves", sm.moves},
                       {"rejected", sm.rejected},
                       {"corner_objective_before", sm.objective_before},
                       {"corner_objective_after", sm.objective_after},
                       {"frozen", sm.frozen},
                       {"redos", sm.redos},
                       {"self_intersections", sm.self_intersections}};
  }
  info(std::string(r.gmsh ? "gmsh: " : "") + std::to_string(qq.quads) + " quads and " + std::to_string(qq.triangles) + " triangles (" +
       format_number(100 * qq.quad_share()) + "% quads), corners within 90 +- 20 deg " +
       format_number(100 * qq.corner_share_70_110()) + "%, valence 4 " + format_number(100 * qq.valence4_share()) +
       "%, scaled Jacobian min " + format_number(qq.jacobian_min) + ", " +
       (qq.boundary_edges == 0 && qq.nonmanifold_edges == 0 ? "watertight" : "NOT watertight"));
}

}  // namespace pm

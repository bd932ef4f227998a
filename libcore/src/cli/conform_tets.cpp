#include "pm/cli/conform_tets.h"

#include <optional>
#include <stdexcept>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/tet_quality.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {
namespace {

// The interface mesh's per-triangle label pairs (face properties label_a, label_b).
std::vector<std::array<int, 2>> interface_labels(const Mesh& m, const std::string& path) {
  const auto a = m.face_ints.find("label_a"), b = m.face_ints.find("label_b");
  if (a == m.face_ints.end() || b == m.face_ints.end())
    throw InputError(quote(path) +
                     ": no face properties label_a and label_b; expected an interface mesh with the "
                     "two materials of every triangle (as tetlabel --materials writes it, .ply or .vtk)");
  std::vector<std::array<int, 2>> l(m.faces.size());
  for (std::size_t f = 0; f < l.size(); ++f) l[f] = {a->second[f], b->second[f]};
  return l;
}

}  // namespace

void add_conform_options(CLI::App& app, ConformRun& r) {
  app.add_option("--conform", r.surface,
                 "Conforming mode: the closed surface (one material) or interface mesh (several, face "
                 "properties label_a < label_b), world units, to keep exactly as the tetrahedra's boundary (.ply .vtk .mesh "
                 ".obj .off .stl)");
  app.add_option("--min-dihedral", r.params.min_dihedral,
                 "With --conform: quality refinement target, degrees (split tetrahedra with a smaller dihedral "
                 "angle or a radius-edge ratio above --radius-edge; next to the kept boundary it can be missed, "
                 "and sliver removal lowers the smallest angle a little: 18 gave 12.5 on the brain); "
                 "0 = no refinement step")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 59.9));
  app.add_option("--radius-edge", r.params.radius_edge,
                 "With --conform: refinement bound on circumradius / shortest edge (dimensionless, > 1)")
      ->capture_default_str()
      ->check(CLI::Range(1.01, 100.0));
  app.add_option("--max-volume", r.params.max_volume,
                 "With --conform: refinement also splits tetrahedra larger than this, world units^3 (TetGen -a); "
                 "0 = no bound")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--max-dihedral", r.params.max_dihedral,
                 "With --conform: sliver removal works on tetrahedra with a dihedral angle above this, degrees")
      ->capture_default_str()
      ->check(CLI::Range(90.1, 179.9));
  app.add_option("--rounds", r.params.rounds,
                 "With --conform: rounds of refinement + sliver removal; a round after the first runs only while "
                 "a dihedral angle below --min-dihedral is left")
      ->capture_default_str()
      ->check(CLI::Range(1, 5));
  app.add_flag("--optimise,!--no-optimise", r.params.optimise,
               "With --conform: sliver removal (TetGen's flips and interior-vertex smoothing; default on)");
  app.add_option("--boundary-clearance", r.params.boundary_clearance,
                 "With --conform: interior points closer to a boundary triangle than this times the triangle's "
                 "longest edge are dropped before meshing (they make flat tetrahedra on the fixed boundary); "
                 "dimensionless, 0 = keep them")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  app.add_option("--exude-rounds", r.params.exude_rounds,
                 "With --conform: when tetrahedra outside [12, 160] degrees survive the smoothing, the interior "
                 "points of those TetGen left outside are removed and the volume meshed again, at most this many "
                 "times (the best meshing is kept); 0 = never")
      ->capture_default_str()
      ->check(CLI::Range(0, 5));
  app.add_option("--smooth", r.params.smooth_sweeps,
                 "With --conform: sweeps of ODT smoothing of the interior vertices after each meshing (moves that keep "
                 "every tetrahedron positive and do not lower the worst radius ratio around the vertex); 0 = none")
      ->capture_default_str()
      ->check(CLI::Range(0, 50));
  app.add_option("--require", r.require,
                 "With --conform: check the final mesh as meshstats --require does (e.g. "
                 "\"min_dihedral>=12,max_dihedral<=160,rr_mean>=0.8,positive,triangles_match\"); exit 3 "
                 "when one fails (the mesh is still written)");
}

void check_conform_options(const ConformRun& r) {
  if (r.tets.empty()) throw UsageError("--conform needs --tets FILE (" + output_extensions(OutputKind::tet_mesh) + ")");
  for (const std::string& f : r.tets) check_output_path(f, OutputKind::tet_mesh, "--tets");
  if (!r.require.empty()) check_tet_requirements(TetQuality{}, r.require);  // unknown items: UsageError
  if (r.materials.spec.empty() && r.field.input.empty() && r.field.implicit.empty())
    throw UsageError(
        "--conform needs the field that labels the volume: -i FILE --iso C (or --implicit SPEC) for "
        "one material, or --materials SPEC for several");
}

void run_conform(const ConformRun& r) {
  check_conform_options(r);
  auto& st = stats();
  const bool multi = !r.materials.spec.empty();
  std::optional<ScopedStage> reading("read");
  Mesh surface = read_mesh(r.surface);
  const Mesh points = read_mesh(r.interior);
  std::vector<std::array<int, 2>> labels;
  std::function<int(const Vec3&)> label_at;
  int outside = 0;
  MaterialSet ms;
  LoadedField lf;
  Json params = {{"min_dihedral", r.params.min_dihedral},
                 {"radius_edge", r.params.radius_edge},
                 {"optimise", r.params.optimise},
                 {"max_dihedral", r.params.max_dihedral},
                 {"optimise_level", r.params.optimise_level},
                 {"boundary_clearance", r.params.boundary_clearance},
                 {"smooth_sweeps", r.params.smooth_sweeps},
                 {"exude_rounds", r.params.exude_rounds},
                 {"max_volume", r.params.max_volume}};
  if (multi) {
    st["inputs"] = {r.interior, r.surface, r.materials.spec};
    labels = interface_labels(surface, r.surface);
    ms = load_materials(r.materials);
    outside = parse_outside_label(r.outside, ms);
    const Box dom = ms.domain();
    label_at = [&ms, dom, outside](const Vec3& x) { return dom.contains(x) ? ms.label_at(x) : outside; };
    params["materials"] = r.materials.spec;
    params["outside_label"] = outside;
  } else {
    st["inputs"] = {r.interior, r.surface, r.field.input.empty() ? r.field.implicit : r.field.input};
    lf = load_field(r.field);
    const bool below = r.inside == "auto" ? material_below_iso(*lf.field, lf.iso) : r.inside == "below";
    const Box dom = lf.field->domain();
    const ScalarField* f = lf.field.get();
    const double iso = lf.iso;
    label_at = [f, dom, iso, below](const Vec3& x) {
      if (!dom.contains(x)) return 0;
      const double v = f->value(x);
      return (below ? v < iso : v > iso) ? 1 : 0;
    };
    labels.assign(surface.faces.size(), {0, 1});
    params["iso"] = iso;
    params["inside"] = below ? "below" : "above";
  }
  reading.reset();
  st["parameters"] = params;
  if (surface.faces.empty())
    throw InputError(quote(r.surface) + ": no triangles; expected the closed surface or interface mesh to keep");
  const ConformResult res =
      conforming_tets(surface, labels, points.vertices, label_at, outside, r.params, quote(r.surface));
  for (int m : res.self_intersection_untested)
    warn(quote(r.surface) + ": the surface of material " + std::to_string(m) +
         " is not a manifold polygon mesh (parts touching at a vertex): not tested for self-intersections");
  if (res.interior_outside + res.interior_near_point + res.interior_near_boundary + res.interior_refused > 0)
    info(quote(r.interior) + ": " + std::to_string(res.interior_kept) + " of " + std::to_string(res.interior_given) +
         " interior points kept (" + std::to_string(res.interior_outside) + " outside every material, " +
         std::to_string(res.interior_near_point) + " on the surface or on another point, " +
         std::to_string(res.interior_near_boundary) + " too close to a boundary triangle, " +
         std::to_string(res.interior_refused) + " refused by TetGen)");
  if (res.split_vote_regions > 0)
    info(std::to_string(res.split_vote_regions) + " of " + std::to_string(res.regions) +
         " regions were labelled by a split vote of their tetrahedra (the smallest winning share " +
         format_number(res.min_vote_share) + " of a region's volume)");
  {
    ScopedStage w("write");
    for (const std::string& f : r.tets) write_tet_mesh(res.mesh, f, {r.frame});
  }
  const Json j = to_json(res);
  st["counts"] = j["counts"];
  st["steps"] = j["steps"];
  st["quality"] = j["steps"].back()["quality"];
  st["outputs"] = r.tets;
  const TetQuality& q = res.steps.back().quality;
  if (verbosity() != Verbosity::quiet) std::fputs(format_table(q).c_str(), stderr);
  if (!r.require.empty()) {
    const auto failed = check_tet_requirements(q, r.require);
    if (!failed.empty()) {
      std::string msg = quote(r.tets.front()) + ": " + std::to_string(failed.size()) + " requirement(s) not met:";
      for (const auto& f : failed) msg += " " + f;
      throw CheckFailed(msg);
    }
  }
}

}  // namespace pm

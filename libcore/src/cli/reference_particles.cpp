#include "pm/cli/reference_particles.h"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/field/hp_field.h"
#include "pm/field/reference_scenarios.h"
#include "pm/io/nektar.h"
#include "pm/io/ply.h"
#include "pm/sample/hp_constraint.h"

namespace pm {
namespace {

// Particles in reference space on any ReferenceField (a Nektar++ field or a
// built-in Chapter 4 scenario), written as a double-precision PLY.
void run_reference(const ReferenceField& field, const ParticleParams& p, const std::string& output) {
  HpParticleParams hp;
  hp.iso = p.iso;
  hp.spacing = p.spacing;
  hp.density = p.density;
  hp.alpha_cap = p.alpha_cap;
  hp.energy = p.energy;
  hp.tolerance = p.tolerance;
  hp.max_iters = p.max_iters;
  hp.population_tolerance = p.population_tolerance;
  hp.seed = p.seed;
  hp.settled_move = p.settled_move;
  hp.coarse_to_fine = p.coarse_to_fine;
  hp.coarse_start = p.coarse_start;
  const HpParticleResult r = distribute_hp_particles(field, hp);
  Mesh m;
  m.vertices = r.positions;
  m.normals = r.normals;
  std::vector<double> elem(r.element.begin(), r.element.end()), x1, x2, x3;
  for (const Vec3& xi : r.xi) {
    x1.push_back(xi.x);
    x2.push_back(xi.y);
    x3.push_back(xi.z);
  }
  m.vertex_scalars["element"] = elem;
  m.vertex_scalars["xi1"] = x1;
  m.vertex_scalars["xi2"] = x2;
  m.vertex_scalars["xi3"] = x3;
  m.vertex_scalars["residual"] = r.residual;
  m.vertex_scalars["energy"] = r.energy;
  m.vertex_scalars["spacing"] = r.spacing;
  {
    ScopedStage stage("write");
    write_atomically(output, [&](const std::string& tmp) { write_ply(m, tmp, true, WorldFrame::lps, true); });
  }
  double worst = 0;
  for (double v : r.residual) worst = std::max(worst, v);
  auto& st = stats();
  st["counts"] = {{"particles", r.positions.size()}, {"iterations", r.iterations}, {"seeds", r.seeds},
                  {"thinned", r.thinned}, {"dropped_init", r.dropped_init}, {"splits", r.splits},
                  {"deletions", r.deletions}, {"field_evaluations", r.field_evaluations},
                  {"map_evaluations", r.map_evaluations}, {"seed_evaluations", r.seed_evaluations}};
  st["engine"] = engine_stats_json(r.engine);
  st["converged"] = r.converged;
  st["max_residual"] = worst;
  st["energy_final"] = r.energy_final;
  st["energy_ideal"] = r.energy_ideal;
  st["mean_neighbours"] = r.mean_neighbours;
  st["outputs"] = {output};
  const std::string stuck = engine_failure_summary(r.engine);
  if (!stuck.empty()) warn(stuck);
  if (!r.converged)
    warn("not converged after " + std::to_string(r.iterations) + " iterations (--max-iters " +
             std::to_string(p.max_iters) + "); the result was written anyway");
  info(std::to_string(r.positions.size()) + " particles on " + field.describe() + ", max |u - iso| " +
           format_number(worst) + ", " + std::to_string(r.field_evaluations) + " field evaluations");
}

}  // namespace

void run_hp(const std::string& mesh_path, const std::string& field_arg, const ParticleParams& p,
            const std::string& output, WorldFrame frame) {
  const std::size_t colon = field_arg.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == field_arg.size())
    throw UsageError("--field expects FILE.fld:VARIABLE (e.g. chan3D.fld:u), got " + quote(field_arg));
  if (frame != WorldFrame::lps)
    throw UsageError("--frame does not apply with --field: the mesh's coordinates are written as they are");
  if (file_extension(output) != ".ply")
    throw UsageError("with --field the output must be .ply (positions are written as double), got " +
                         quote(output));
  const std::string fld_path = field_arg.substr(0, colon), var = field_arg.substr(colon + 1);
  std::unique_ptr<ScopedStage> read = std::make_unique<ScopedStage>("read");
  const NektarMesh mesh = read_nektar_mesh(mesh_path);
  const NektarField fld = read_nektar_field(fld_path);
  bool has = false;
  std::string names;
  for (const auto& n : fld.names) {
    has = has || n == var;
    names += (names.empty() ? "" : " ") + n;
  }
  if (!has)
    throw InputError("field " + quote(fld_path) + " has no variable " + quote(var) +
                         "; expected one of: " + names);
  const HpField field(mesh, fld, var);
  read.reset();
  run_reference(field, p, output);
}

// Chapter 4 scenarios built in code: the B-spline-mapped teardrop (F* =
// |u - c|^2 in reference space, default iso 0.16: radius 0.4) and hex8
// (u = x^8 + y^8 + z^8 in the hexahedron [-1,1]^3, default iso 0.5).
void run_scenario(const std::string& name, ParticleParams p, bool iso_given, const std::string& output) {
  if (file_extension(output) != ".ply")
    throw UsageError("with --scenario the output must be .ply (positions are written as double), got " +
                         quote(output));
  if (name == "teardrop") {
    const TeardropField field;
    if (!iso_given) p.iso = field.iso();
    stats()["parameters"]["iso"] = p.iso;
    return run_reference(field, p, output);
  }
  const HexPowerScenario s = hex_power_field(8, {-1, -1, -1}, {1, 1, 1});
  const HpField field(s.mesh, s.field, "u");
  if (!iso_given) p.iso = 0.5;
  stats()["parameters"]["iso"] = p.iso;
  run_reference(field, p, output);
}

}  // namespace pm

#include "pm/cli/multiparticles_run.h"

#include <memory>
#include <string>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/material_options.h"
#include "pm/cli/energy_option.h"
#include "pm/cli/run_tool.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/sample/multiparticles.h"
#include "pm/volume/mcinit.h"

namespace pm {
namespace {

void record_stats(const pm::MultiParticleResult& r) {
  auto& st = pm::stats();
  const char* names[3] = {"points", "curves", "surfaces"};
  pm::Json levels = pm::Json::object();
  for (int l = 0; l < 3; ++l) {
    const pm::MultiLevelStats& s = r.levels[std::size_t(l)];
    levels[names[l]] = {{"particles", s.particles},
                        {"cells", s.cells},
                        {"seeds", s.seeds},
                        {"seeds_unknown_label", s.seeds_unknown},
                        {"seeds_failed", s.seeds_failed},
                        {"seeds_culled", s.seeds_culled},
                        {"iterations", s.iterations},
                        {"converged", s.converged},
                        {"splits", s.splits},
                        {"deletions", s.deletions},
                        {"energy_final", s.energy_final},
                        {"energy_ideal", s.energy_ideal}};
    pm::add_seconds(names[l], s.seconds);
  }
  st["levels"] = levels;
  st["counts"] = {{"particles", r.positions.size()},
                  {"field_evaluations", r.field_evaluations},
                  {"junction_repairs", r.junction_repairs}, {"close_pairs_merged", r.close_pairs_merged},
                  {"corner_repairs", r.corner_repairs}, {"curve_pairs_dropped", r.curve_pairs_dropped}};
  st["engine"] = pm::engine_stats_json(r.engine);
  st["max_residual"] = r.max_residual;
}

}  // namespace

void add_multiparticles_options(CLI::App& app, MultiParticlesRun& cfg) {
  pm::add_material_options(app, cfg.materials);
  app.add_option("--seeds", cfg.seeds_path,
                 "Junction seeds (PLY with vertex scalars junction, label_a..label_d as "
                 "written by mcinit --junctions)");
  app.add_option("--labels", cfg.labels_path,
                 "Label map to compute junction seeds from (pm::junction_seeds; "
                 "labels must match the materials' labels)");
  app.add_option("--decimate", cfg.decimate,
                 "With --labels or the default grid: keep about one seed per "
                 "N^3 cells per label set")
      ->capture_default_str();
  cfg.spacing = app.add_option("--spacing", cfg.params.spacing,
                               "Uniform particle spacing s, world units; required "
                               "unless --sizing");
  app.add_option("--sizing", cfg.sizing_path,
                 "Sizing field volume h (world units, > 0, trilinear), e.g. the "
                 "minimum over the materials; must cover the junctions");
  pm::add_energy_option(app, cfg.energy);
  app.add_option("--tolerance", cfg.params.tolerance,
                 "A level has converged when the energy drops by less than this "
                 "fraction in one iteration")
      ->capture_default_str();
  app.add_option("--max-iters", cfg.params.max_iters,
                 "Iteration limit per level (curves, surfaces); not converging is "
                 "a warning")
      ->capture_default_str();
  app.add_option("--population-tolerance", cfg.params.population_tolerance,
                 "Converged when at most this fraction of a level's particles wants to split or die")
      ->capture_default_str();
  pm::add_step_options(app, cfg.params.step_control, cfg.params.step_factor,
                       "factor is the default here: quadratic measured 2-3x slower on label maps");
  app.add_flag("--no-surfaces", cfg.no_surfaces, "Stop after the curves (points and curves only)");
  app.add_flag("--no-junction-repair", cfg.no_repair,
               "Keep surface particles closer than h/4 (by default two of interfaces sharing a material "
               "become one particle on their triple junction, where the curve level left a gap, and two of "
               "one interface, on the two faces of a fin thinner than the spacing, one at their middle)");
  app.add_option("-o,--output", cfg.output, "Output point set (.ply .vtp .vtk), world units")->required();

  pm::add_frame_option(app, cfg.frame);
}

void run_multiparticles(MultiParticlesRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& mo = cfg.materials;
  [[maybe_unused]] auto& seeds_path = cfg.seeds_path;
  [[maybe_unused]] auto& labels_path = cfg.labels_path;
  [[maybe_unused]] auto& sizing_path = cfg.sizing_path;
  [[maybe_unused]] auto& output = cfg.output;
  [[maybe_unused]] auto& energy = cfg.energy;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& decimate = cfg.decimate;
  [[maybe_unused]] auto& no_surfaces = cfg.no_surfaces;
  [[maybe_unused]] auto& no_repair = cfg.no_repair;
  [[maybe_unused]] auto& spacing = cfg.spacing;
  [[maybe_unused]] auto& frame = cfg.frame;
  pm::check_output_path(output, pm::OutputKind::points, "--output");
  if (sizing_path.empty() && !spacing->count())
    throw pm::UsageError("--spacing S (world units) or --sizing H is required");
  if (!sizing_path.empty() && spacing->count()) throw pm::UsageError("give --spacing or --sizing, not both");
  if (!seeds_path.empty() && !labels_path.empty()) throw pm::UsageError("give --seeds or --labels, not both");
  if (decimate < 1) throw pm::UsageError("--decimate must be >= 1, got " + std::to_string(decimate));
  p.energy = pm::energy_named(energy);
  p.surfaces = !no_surfaces;
  p.repair_junctions = !no_repair;
  p.seed = flags.seed;
  p.progress = !flags.quiet;

  auto& st = pm::stats();
  st["inputs"] = {{"materials", mo.spec}, {"seeds", seeds_path}, {"labels", labels_path}, {"sizing", sizing_path}};
  st["parameters"] = {{"spacing", p.spacing},     {"energy", energy},
                      {"tolerance", p.tolerance}, {"max_iters", p.max_iters}, {"step_factor", p.step_factor},
                      {"step_control", pm::step_control_name(p.step_control)},
                      {"kernel", mo.kernel},      {"decimate", decimate},
                      {"surfaces", p.surfaces},   {"population_tolerance", p.population_tolerance}};
  pm::MaterialSet mats;
  {
    pm::ScopedStage stage("read");
    mats = pm::load_materials(mo);
  }
  if (mats.size() < 2)
    throw pm::InputError("--materials " + pm::quote(mo.spec) + " has " + std::to_string(mats.size()) +
                         " material(s); expected at least 2");
  std::unique_ptr<pm::SizingField> sizing;
  if (!sizing_path.empty()) sizing = std::make_unique<pm::SizingField>(pm::read_volume(sizing_path), sizing_path);

  std::vector<pm::JunctionSeed> seeds;
  {
    pm::ScopedStage stage("seeds");
    if (!seeds_path.empty()) {
      seeds = pm::junction_seeds_from_mesh(pm::read_mesh(seeds_path), seeds_path);
    } else if (!labels_path.empty()) {
      pm::JunctionParams jp;
      jp.decimate = decimate;
      seeds = pm::junction_seeds_from_mesh(pm::junction_seeds(pm::read_volume(labels_path), jp).seeds, labels_path);
    } else {
      seeds = pm::junction_seeds_from_materials(mats);
    }
    if (seeds.empty())
      throw pm::InputError("no junction seeds" + (seeds_path.empty() ? std::string() : " in " + pm::quote(seeds_path)) +
                           "; expected points on the material boundaries");
  }
  const pm::MultiParticleResult r = pm::distribute_multi_particles(mats, seeds, sizing.get(), p);
  record_stats(r);
  {
    pm::ScopedStage stage("write");
    pm::write_mesh(pm::multi_particles_mesh(r), output, {true, frame});
  }
  st["outputs"] = {output};
  const char* names[3] = {"points", "curves", "surfaces"};
  std::string summary;
  for (int l = 0; l < 3; ++l) {
    const pm::MultiLevelStats& s = r.levels[std::size_t(l)];
    summary += (l ? ", " : "") + std::to_string(s.particles) + " on " + std::to_string(s.cells) + " " + names[l];
    if (l > 0 && s.particles && !s.converged)
      pm::warn(std::string(names[l]) + " not converged after " + std::to_string(s.iterations) +
               " iterations (--max-iters " + std::to_string(p.max_iters) + "); the result was written anyway");
  }
  const std::string stuck = pm::engine_failure_summary(r.engine);
  if (!stuck.empty()) pm::warn(stuck);
  pm::info(summary);
}

}  // namespace pm

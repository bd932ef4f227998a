#include "pm/cli/mcinit_run.h"

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/mcinit.h"

namespace pm {

void add_mcinit_options(CLI::App& app, McInitRun& cfg) {
  cfg.iso = app.add_option("--iso", cfg.params.iso, "Isovalue, in voxel value units (F < iso inside)");
  app.add_option("input", cfg.input, "Input volume (grey values, distance field, mask; label map with --junctions)")
      ->required();
  app.add_option("output", cfg.output, "Seed points (.ply .vtp .vtk: vertices, normals, scalars), world units")
      ->required();
  pm::add_kernel_option(app, cfg.kernel);
  app.add_option("--decimate", cfg.params.decimate, "Keep about one seed per K^3 cells (per component / label set)")
      ->capture_default_str();
  app.add_option("--project-steps", cfg.params.project_steps, "Newton steps onto the isosurface (0 = raw edge points)")
      ->capture_default_str();
  app.add_flag("--junctions", cfg.junctions, "Label map: seeds on material boundaries, triple lines, quadruple points");

  pm::add_frame_option(app, cfg.frame);
}

void run_mcinit(McInitRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& kernel = cfg.kernel;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& junctions = cfg.junctions;
  [[maybe_unused]] auto& iso = cfg.iso;
  [[maybe_unused]] auto& frame = cfg.frame;
  pm::check_output_path(out, pm::OutputKind::points, "output");
  auto& st = pm::stats();
  if (p.decimate < 1) throw pm::UsageError("--decimate " + std::to_string(p.decimate) + "; expected >= 1");
  p.field = pm::kernel_params(kernel);
  if (junctions == (iso->count() > 0))
    throw pm::UsageError(junctions ? "--junctions takes no --iso" : "--iso C is required (or --junctions)");
  st["inputs"] = {in};
  st["parameters"] = {{"iso", p.iso}, {"kernel", kernel}, {"decimate", p.decimate}, {"junctions", junctions}};
  const pm::Volume v = pm::read_volume(in);
  pm::ScopedStage stage("seeds");
  pm::Mesh seeds;
  try {
    if (junctions) {
      pm::JunctionResult r = pm::junction_seeds(v, {p.decimate});
      pm::Json pairs = pm::Json::object();
      for (const auto& [ab, n] : r.pairs) pairs[std::to_string(ab.first) + "-" + std::to_string(ab.second)] = n;
      st["counts"] = {
          {"seeds", r.seeds.vertices.size()}, {"pairs", pairs}, {"triples", r.triples}, {"quadruples", r.quadruples}};
      seeds = std::move(r.seeds);
    } else {
      pm::McInitResult r = pm::mc_seeds(v, p);
      st["counts"] = {{"seeds", r.seeds.vertices.size()},
                      {"crossings", r.crossings},
                      {"components", r.components},
                      {"projected", r.projected},
                      {"max_residual", r.max_residual}};
      pm::info(std::to_string(r.seeds.vertices.size()) + " seeds on " + std::to_string(r.components) + " components (" +
               std::to_string(r.crossings) + " crossing edges)");
      seeds = std::move(r.seeds);
    }
  } catch (const pm::InputError& e) {
    throw pm::InputError(pm::quote(in) + ": " + e.what());
  }
  pm::write_mesh(seeds, out, {true, frame});
  st["outputs"] = {out};
}

}  // namespace pm

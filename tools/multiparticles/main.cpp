// multiparticles: hierarchical particle sampling of the junctions of a
// multi-material volume (SPEC §6, Meyer 2008 Chapter 6): quadruple points,
// triple curves, then the interfaces between each pair of materials.
#include <memory>
#include <string>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/material_options.h"
#include "pm/cli/run_tool.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/io/volume_io.h"
#include "pm/volume/mcinit.h"
#include "pm/sample/multiparticles.h"
#include "pm/cli/frame_option.h"
#include "pm/io/output_path.h"

namespace {

void record_stats(const pm::MultiParticleResult& r) {
  auto& st = pm::stats();
  const char* names[3] = {"points", "curves", "surfaces"};
  pm::Json levels = pm::Json::object();
  for (int l = 0; l < 3; ++l) {
    const pm::MultiLevelStats& s = r.levels[std::size_t(l)];
    levels[names[l]] = {{"particles", s.particles},     {"cells", s.cells},
                        {"seeds", s.seeds},             {"seeds_unknown_label", s.seeds_unknown},
                        {"seeds_failed", s.seeds_failed}, {"seeds_culled", s.seeds_culled},
                        {"iterations", s.iterations},   {"converged", s.converged},
                        {"splits", s.splits},           {"deletions", s.deletions},
                        {"energy_final", s.energy_final}, {"energy_ideal", s.energy_ideal}};
    pm::add_seconds(names[l], s.seconds);
  }
  st["levels"] = levels;
  st["counts"] = {{"particles", r.positions.size()},
                  {"field_evaluations", r.field_evaluations},
                  {"junction_repairs", r.junction_repairs}};
  st["engine"] = pm::engine_stats_json(r.engine);
  st["max_residual"] = r.max_residual;
}

}  // namespace

int main(int argc, char** argv) {
  pm::Tool tool(
      "multiparticles",
      "Sample every junction of a multi-material volume with particles (world units throughout): one particle "
      "on each quadruple point (0-cell), chains along each triple curve (1-cells), then near-hexagonal "
      "packings on each interface between two materials (2-cells); each level relaxes while the lower ones stay "
      "fixed and repel it. Junctions are found from seeds: `mcinit --junctions` points (--seeds), a label map "
      "(--labels), or by default the argmax labels of the materials on a grid at their resolution. Output: a PLY "
      "point set with x y z, nx ny nz (surfaces: unit normal from label_a into label_b; zero on curves and "
      "points) and vertex scalars junction (number of materials meeting: 4 point, 3 curve, 2 surface), label_a < "
      "label_b < label_c < label_d (-1 unused), spacing (local h, world units), energy, residual (max |f_a - f_b| "
      "at the particle, world units).",
      "multiparticles --materials labels.nrrd --spacing 2 -o points.ply --stats -");
  pm::MaterialOptions mo;
  pm::add_material_options(tool.app, mo);
  std::string seeds_path, labels_path, sizing_path, output, energy = "cotangent";
  pm::MultiParticleParams p;
  int decimate = 1;
  bool no_surfaces = false, no_repair = false;
  tool.app.add_option("--seeds", seeds_path, "Junction seeds (PLY with vertex scalars junction, label_a..label_d as "
                                             "written by mcinit --junctions)");
  tool.app.add_option("--labels", labels_path, "Label map to compute junction seeds from (pm::junction_seeds; "
                                               "labels must match the materials' labels)");
  tool.app.add_option("--decimate", decimate, "With --labels or the default grid: keep about one seed per "
                                              "N^3 cells per label set")
      ->capture_default_str();
  auto* spacing = tool.app.add_option("--spacing", p.spacing, "Uniform particle spacing s, world units; required "
                                                              "unless --sizing");
  tool.app.add_option("--sizing", sizing_path, "Sizing field volume h (world units, > 0, trilinear), e.g. the "
                                               "minimum over the materials; must cover the junctions");
  tool.app.add_option("--energy", energy, "Pair energy: cotangent or radial")
      ->check(CLI::IsMember({"cotangent", "radial"}))
      ->capture_default_str();
  tool.app.add_option("--tolerance", p.tolerance, "A level has converged when the energy drops by less than this "
                                                  "fraction in one iteration")
      ->capture_default_str();
  tool.app.add_option("--max-iters", p.max_iters, "Iteration limit per level (curves, surfaces); not converging is "
                                                  "a warning")
      ->capture_default_str();
  tool.app.add_option("--population-tolerance", p.population_tolerance,
                      "Converged when at most this fraction of a level's particles wants to split or die")
      ->capture_default_str();
  tool.app.add_flag("--no-surfaces", no_surfaces, "Stop after the curves (points and curves only)");
  tool.app.add_flag("--no-junction-repair", no_repair,
                    "Keep surface particles of two interfaces sharing a material that come closer than h/4 (by "
                    "default such a pair becomes one particle on their triple junction, where the curve level "
                    "left a gap)");
  tool.app.add_option("-o,--output", output, "Output point set (.ply .vtp .vtk), world units")->required();

  pm::WorldFrame frame = pm::WorldFrame::lps;
  pm::add_frame_option(tool.app, frame);
  return tool.run(argc, argv, [&] {
    pm::check_output_path(output, pm::OutputKind::points, "--output");
    if (sizing_path.empty() && !spacing->count()) throw pm::UsageError("--spacing S (world units) or --sizing H is required");
    if (!sizing_path.empty() && spacing->count()) throw pm::UsageError("give --spacing or --sizing, not both");
    if (!seeds_path.empty() && !labels_path.empty()) throw pm::UsageError("give --seeds or --labels, not both");
    if (decimate < 1) throw pm::UsageError("--decimate must be >= 1, got " + std::to_string(decimate));
    p.energy = energy == "radial" ? pm::ParticleEnergy::radial : pm::ParticleEnergy::cotangent;
    p.surfaces = !no_surfaces;
    p.repair_junctions = !no_repair;
    p.seed = tool.flags.seed;
    p.progress = !tool.flags.quiet;

    auto& st = pm::stats();
    st["inputs"] = {{"materials", mo.spec}, {"seeds", seeds_path}, {"labels", labels_path}, {"sizing", sizing_path}};
    st["parameters"] = {{"spacing", p.spacing},     {"energy", energy},       {"tolerance", p.tolerance},
                        {"max_iters", p.max_iters}, {"kernel", mo.kernel},    {"decimate", decimate},
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
  });
}

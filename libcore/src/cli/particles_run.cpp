#include "pm/cli/particles_run.h"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/reference_particles.h"
#include "pm/cli/energy_option.h"
#include "pm/cli/run_tool.h"
#include "pm/cli/volume_particles.h"
#include "pm/field/implicits.h"
#include "pm/field/sizing.h"
#include "pm/field/volume_field.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/sample/particles.h"

namespace pm {
namespace {

// The field to sample: an analytic implicit or a reconstructed volume whose
// value range must straddle the isovalue (pm::load_field).
std::unique_ptr<pm::ScalarField> load_field(const std::string& implicit, const std::string& input,
                                            const std::string& kernel, double iso) {
  pm::ScopedStage stage("read");
  return std::move(pm::load_field(pm::FieldOptions{input, implicit, kernel, iso}).field);
}

void record_stats(const pm::ParticleResult& r) {
  auto& st = pm::stats();
  pm::add_seconds("init", r.seconds_init);
  pm::add_seconds("relax", r.seconds_relax);
  pm::add_seconds("population", r.seconds_population);
  pm::add_seconds("finish", r.seconds_finish);
  st["counts"] = {{"particles", r.positions.size()},
                  {"iterations", r.iterations},
                  {"levels", r.levels},
                  {"splits", r.splits},
                  {"deletions", r.deletions},
                  {"dropped_init", r.dropped_init},
                  {"refilled", r.refilled},
                  {"thinned", r.thinned},
                  {"list_builds", r.list_builds},
                  {"field_evaluations", r.field_evaluations},
                  {"particle_updates", r.particle_updates}};
  st["engine"] = pm::engine_stats_json(r.engine);
  st["converged"] = r.converged;
  st["energy_final"] = r.energy_final;
  st["energy_ideal"] = r.energy_ideal;
  st["mean_neighbours"] = r.mean_neighbours;
  st["final_spacing"] = r.final_spacing;
}

pm::Mesh to_mesh(const pm::ParticleResult& r) {
  pm::Mesh m;
  m.vertices = r.positions;
  m.normals = r.normals;
  m.vertex_scalars["energy"] = r.energy;
  m.vertex_scalars["spacing"] = r.spacing;
  m.vertex_scalars["curvature"] = r.curvature;
  if (!r.types.empty()) m.vertex_scalars["type"].assign(r.types.begin(), r.types.end());
  return m;
}

}  // namespace

void add_particles_options(CLI::App& app, ParticlesRun& cfg) {
  app.add_option("--implicit", cfg.implicit, "Analytic surface: " + pm::implicit_help());
  app.add_option("-i,--input", cfg.input,
                 "Volume to sample (.nrrd .nhdr .vdb .mha .nii .inr), geometry from its "
                 "header");
  app.add_option("--field", cfg.hp_field,
                 "Chapter 4: a Nektar++ field FILE.fld:VARIABLE on the mesh -i MESH.xml (straight-sided tets "
                 "and hexes); particles live in each element's reference space, are projected by Newton on the "
                 "element polynomial (|u - iso| <= 1e-12) and cross element faces. Output: .ply with double x y z "
                 "(mesh units), nx ny nz, element (Nektar++ id), xi1 xi2 xi3, residual |u - iso|, energy, spacing");
  app.add_option("--scenario", cfg.scenario,
                 "Chapter 4 scenario built in code (no -i): teardrop = sphere |u - c|^2 = iso (default 0.16) "
                 "in the reference space of 8 quadratic B-spline elements mapped to a teardrop (world height "
                 "2); hex8 = x^8 + y^8 + z^8 = iso (default 0.5) in one hexahedron [-1,1]^3. Output as with "
                 "--field")
      ->check(CLI::IsMember({"teardrop", "hex8"}));
  cfg.iso_opt = app.add_option("--iso", cfg.params.iso, "Isovalue (volume: strictly between its min and max voxel)")
                    ->capture_default_str();
  cfg.spacing = app.add_option("--spacing", cfg.params.spacing,
                               "Spacing s between particles on flat parts, world units (from the volume "
                               "header); required unless --sizing");
  cfg.density = app.add_option("--density", cfg.params.density,
                               "Curvature adaptivity rho, particles per radian: local spacing "
                               "s/(1 + rho s C/(2 pi)), C = curvedness; 0 = uniform")
                    ->capture_default_str();
  app.add_option("--alpha-cap", cfg.params.alpha_cap, "With --density: local spacing never below s / CAP")
      ->capture_default_str();
  app.add_option("--sizing", cfg.sizing_path,
                 "Sizing field volume h (world units, > 0, trilinear) instead of "
                 "--spacing/--density; must cover the surface");
  app.add_option("--init", cfg.seeds_path,
                 "Seed points (PLY vertices, world units) instead of random points, e.g. "
                 "marching-cubes vertices so that every component is seeded");
  app.add_option("--init-count", cfg.params.init_count, "Random initial points in the field's domain")
      ->capture_default_str();
  cfg.lattice = app.add_flag("--lattice-init,!--no-lattice-init", cfg.params.init_lattice,
                             "Without --init: start from the crossings of the surface with a lattice of "
                             "step 1.15 x the starting spacing instead of --init-count random points "
                             "(default: on for volumes, off for --implicit)");
  app.add_option("--count", cfg.params.count,
                 "Keep exactly N particles, scaling the spacing (or h) instead of "
                 "splitting/deleting; --spacing is the starting value");
  app.add_option("--kernel", cfg.kernel,
                 "Volume reconstruction: bspline (C2, approximating), catmull-rom "
                 "(interpolating) or mix (value Catmull-Rom, derivatives B-spline)")
      ->check(CLI::IsMember({"bspline", "catmull-rom", "mix"}))
      ->capture_default_str();
  pm::add_energy_option(app, cfg.energy);
  cfg.tol_opt = app.add_option("--tolerance", cfg.params.tolerance,
                               "Converged when the system energy drops by less than this "
                               "fraction in one iteration")
                    ->capture_default_str();
  cfg.coarse_tol_opt =
      app.add_option("--coarse-tolerance", cfg.params.coarse_tolerance,
                     "Coarse-to-fine: the tolerance of every level but the last, at least --tolerance (a coarse "
                     "level is split and relaxed again; 0 = --tolerance; --quads: --tolerance unless given)")
          ->capture_default_str();
  cfg.coarse_pop_opt =
      app.add_option("--coarse-population-tolerance", cfg.params.coarse_population_tolerance,
                     "Coarse-to-fine: the population tolerance of every level but the last, at least "
                     "--population-tolerance (0 = --population-tolerance; --quads: the same unless given)")
          ->capture_default_str();
  app.add_option("--population-tolerance", cfg.params.population_tolerance,
                 "Stop when converged and at most this fraction of particles wants to split or die (0 = none)")
      ->capture_default_str();
  app.add_flag("--population,!--no-population", cfg.params.population_control,
               "Population control: split/delete particles towards the ideal energy (--no-population keeps "
               "the initial particles, e.g. --init-count N with --no-lattice-init)")
      ->capture_default_str();
  cfg.iters_opt = app.add_option("--max-iters", cfg.params.max_iters,
                                 "Iteration limit per coarse-to-fine level (not converging is a "
                                 "warning)")
                      ->capture_default_str();
  cfg.ctf = app.add_flag("--coarse-to-fine,!--no-coarse-to-fine", cfg.coarse,
                         "Converge with spacings x 2^k, split each particle into 4, halve, repeat down to "
                         "the requested spacing (default: on for volumes, off for --implicit and --field)");
  app.add_option("--coarse-start", cfg.params.coarse_start,
                 "Coarsest spacing, world units (0 = 4 voxel widths / "
                 "field resolutions)")
      ->capture_default_str();
  app.add_option("--thin-seeds", cfg.params.seed_thinning,
                 "With --init: drop seeds closer than this fraction of the starting local spacing to a kept "
                 "seed before relaxing (0 = keep all; every seed still anchors its component)")
      ->check(CLI::Range(0.0, 1.99))
      ->capture_default_str();
  app.add_option("--settle", cfg.params.settled_move,
                 "Skip updating a particle while it and its neighbours move less than this fraction of its "
                 "spacing per iteration, re-checking it every 8 iterations (0 = off)")
      ->check(CLI::Range(0.0, 0.99))
      ->capture_default_str();
  cfg.step_control_opt = pm::add_step_options(
      app, cfg.params.step_control, cfg.params.step_factor,
      "quadratic is the default here (--quads: factor unless given; --volume and --field always use factor): about half the "
      "updates on the folded brain mask, packing at least as well");
  app.add_flag("--quads", cfg.params.quads,
               "Quad packing (Chapter 7): two particle types, like pairs √2 farther apart than unlike ones, "
               "settling towards a checkerboard on a square lattice with unlike neighbours --spacing apart; "
               "writes a vertex property `type` (0/1) for quadmesh");
  app.add_flag("--volume", cfg.volume,
               "Chapter 7 volume packing: free particles inside the material side of iso "
               "(--inside; or inside every "
               "material of --materials), 12 ideal neighbours, repelled by the fixed "
               "vertices of --fixed; spacing from --sizing (e.g. gradlimit --inward) or "
               "--spacing. Output: x y z, spacing, label");
  app.add_option("--fixed", cfg.vr.fixed,
                 "With --volume: the final surface or interface mesh (.ply from tetlabel); "
                 "its vertices stay fixed and bound the packing");
  app.add_option("--inside", cfg.vr.inside,
                 "With --volume -i/--implicit: which side is the material: below (F < iso, distance fields), "
                 "above (F > iso, masks, CT) or auto (the side the domain's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  pm::add_material_options(app, cfg.materials, false, "--material-kernel");
  app.add_option("--outside", cfg.vr.outside,
                 "With --volume --materials: the label not packed (auto = the "
                 "material touching the volume's border)")
      ->capture_default_str();
  app.add_option("-o,--output", cfg.output, "Output point set (.ply .vtp .vtk), world units")->required();

  pm::add_frame_option(app, cfg.frame);
}

void run_particles(ParticlesRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& implicit = cfg.implicit;
  [[maybe_unused]] auto& input = cfg.input;
  [[maybe_unused]] auto& hp_field = cfg.hp_field;
  [[maybe_unused]] auto& sizing_path = cfg.sizing_path;
  [[maybe_unused]] auto& seeds_path = cfg.seeds_path;
  [[maybe_unused]] auto& output = cfg.output;
  [[maybe_unused]] auto& kernel = cfg.kernel;
  [[maybe_unused]] auto& energy = cfg.energy;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& coarse = cfg.coarse;
  [[maybe_unused]] auto& scenario = cfg.scenario;
  [[maybe_unused]] auto& iso_opt = cfg.iso_opt;
  [[maybe_unused]] auto& spacing = cfg.spacing;
  [[maybe_unused]] auto& density = cfg.density;
  [[maybe_unused]] auto& lattice = cfg.lattice;
  [[maybe_unused]] auto& tol_opt = cfg.tol_opt;
  [[maybe_unused]] auto& iters_opt = cfg.iters_opt;
  [[maybe_unused]] auto& ctf = cfg.ctf;
  [[maybe_unused]] auto& volume = cfg.volume;
  [[maybe_unused]] auto& vr = cfg.vr;
  [[maybe_unused]] auto& mo = cfg.materials;
  [[maybe_unused]] auto& frame = cfg.frame;
  pm::check_output_path(output, pm::OutputKind::points, "--output");
  p.seed = flags.seed;
  p.energy = pm::energy_named(energy);
  if (p.quads && (volume || !scenario.empty() || !hp_field.empty()))
    throw pm::UsageError("--quads samples a surface: not with --volume, --scenario or --field");
  if (p.quads && !tol_opt->count()) p.tolerance = pm::engine_constants::kQuadTolerance;
  // Quad packing recolours over its first sweeps, whichever level they fall in: its levels keep one tolerance.
  if (p.quads && !cfg.coarse_tol_opt->count()) p.coarse_tolerance = 0;
  if (p.quads && !cfg.coarse_pop_opt->count()) p.coarse_population_tolerance = 0;
  // The quadratic step left more defects in the checkerboards (docs/results ch7quads: the
  // sphere's valence-4 share 91.5% -> 85.9%).
  if (p.quads && !cfg.step_control_opt->count()) p.step_control = pm::StepControl::factor;
  if (volume) {
    if (!scenario.empty() || !hp_field.empty() || !seeds_path.empty() || p.count)
      throw pm::UsageError("--scenario, --field, --init and --count do not apply with --volume");
    if (sizing_path.empty() == !spacing->count()) throw pm::UsageError("--volume needs --sizing H or --spacing S");
    std::unique_ptr<pm::ScalarField> field;
    if (!implicit.empty() || !input.empty()) {
      if (!implicit.empty() && !input.empty()) throw pm::UsageError("give one of --implicit SPEC or -i VOLUME");
      field = load_field(implicit, input, kernel, p.iso);
    }
    vr.field = field.get();
    vr.iso = p.iso;
    vr.materials = mo.spec.empty() ? nullptr : &mo;
    vr.sizing = sizing_path;
    vr.params.spacing = p.spacing;
    vr.params.energy = p.energy;
    vr.params.seed = p.seed;
    vr.params.progress = !flags.quiet;
    if (tol_opt->count()) vr.params.tolerance = p.tolerance;
    if (iters_opt->count()) vr.params.max_iters = p.max_iters;
    vr.params.population_control = p.population_control;
    vr.output = output;
    vr.frame = frame;
    return pm::run_volume(vr);
  }
  if (!mo.spec.empty() || !vr.fixed.empty() || vr.inside != "auto")
    throw pm::UsageError("--materials, --fixed and --inside need --volume");
  if (!scenario.empty()) {
    if (!input.empty() || !implicit.empty() || !hp_field.empty())
      throw pm::UsageError("--scenario takes no -i, --implicit or --field");
    if (!spacing->count()) throw pm::UsageError("--spacing S (world units) is required");
    if (!sizing_path.empty() || !seeds_path.empty() || p.count || lattice->count())
      throw pm::UsageError("--sizing, --init, --count and --lattice-init do not apply with --scenario");
    p.coarse_to_fine = ctf->count() ? coarse : false;
    pm::stats()["inputs"] = {{"scenario", scenario}};
    pm::stats()["parameters"] = {{"iso", p.iso}, {"spacing", p.spacing}, {"density", p.density}};
    return pm::run_scenario(scenario, p, iso_opt->count() > 0, output);
  }
  if (!hp_field.empty()) {
    if (input.empty() || !implicit.empty()) throw pm::UsageError("--field needs -i MESH.xml (and no --implicit)");
    if (!spacing->count()) throw pm::UsageError("--spacing S (world units of the mesh) is required");
    if (!sizing_path.empty() || !seeds_path.empty() || p.count || lattice->count())
      throw pm::UsageError("--sizing, --init, --count and --lattice-init do not apply with --field");
    p.coarse_to_fine = ctf->count() ? coarse : false;
    pm::stats()["inputs"] = {{"mesh", input}, {"field", hp_field}};
    pm::stats()["parameters"] = {{"iso", p.iso}, {"spacing", p.spacing}, {"density", p.density}};
    return pm::run_hp(input, hp_field, p, output, frame);
  }
  if (implicit.empty() == input.empty()) throw pm::UsageError("give exactly one of --implicit SPEC or -i VOLUME");
  if (sizing_path.empty() && !spacing->count()) throw pm::UsageError("--spacing S (world units) is required");
  if (!sizing_path.empty() && spacing->count()) throw pm::UsageError("give --spacing or --sizing, not both");
  if (!sizing_path.empty() && density->count()) throw pm::UsageError("--density does not apply with --sizing");
  p.energy = pm::energy_named(energy);
  p.coarse_to_fine = ctf->count() ? coarse : !input.empty();
  if (!lattice->count()) p.init_lattice = !input.empty();
  p.seed = flags.seed;

  auto& st = pm::stats();
  st["inputs"] = {{"field", implicit.empty() ? input : implicit}, {"sizing", sizing_path}, {"init", seeds_path}};
  st["parameters"] = {{"iso", p.iso},
                      {"spacing", p.spacing},
                      {"density", p.density},
                      {"alpha_cap", p.alpha_cap},
                      {"kernel", kernel},
                      {"energy", energy},
                      {"tolerance", p.tolerance},
                      {"coarse_tolerance", p.coarse_tolerance},
                      {"max_iters", p.max_iters},
                      {"count", p.count},
                      {"init_count", p.init_count},
                      {"init_lattice", p.init_lattice},
                      {"population_control", p.population_control},
                      {"coarse_to_fine", p.coarse_to_fine},
                      {"population_tolerance", p.population_tolerance},
                      {"coarse_population_tolerance", p.coarse_population_tolerance},
                      {"seed_thinning", p.seed_thinning},
                      {"settled_move", p.settled_move},
                      {"step_factor", p.step_factor},
                      {"step_control", pm::step_control_name(p.step_control)},
                      {"quads", p.quads}};
  const std::unique_ptr<pm::ScalarField> field = load_field(implicit, input, kernel, p.iso);
  std::unique_ptr<pm::SizingField> sizing;
  if (!sizing_path.empty()) sizing = std::make_unique<pm::SizingField>(pm::read_volume(sizing_path), sizing_path);
  std::vector<pm::Vec3> seeds;
  if (!seeds_path.empty()) {
    seeds = pm::read_mesh(seeds_path).vertices;
    if (seeds.empty()) throw pm::InputError("seed file " + pm::quote(seeds_path) + " has no vertices");
  }

  const pm::ParticleResult r = pm::distribute_particles(*field, seeds, sizing.get(), p);
  record_stats(r);
  {
    pm::ScopedStage stage("write");
    pm::write_mesh(to_mesh(r), output, {true, frame});
  }
  st["outputs"] = {output};
  const std::string stuck = pm::engine_failure_summary(r.engine);
  if (!stuck.empty()) pm::warn(stuck);
  if (!r.converged)
    pm::warn("not converged after " + std::to_string(r.iterations) + " iterations (--max-iters " +
             std::to_string(p.max_iters) + " per level); the result was written anyway");
  pm::info(std::to_string(r.positions.size()) + " particles, " + std::to_string(r.iterations) + " iterations" +
           (r.dropped_init ? ", " + std::to_string(r.dropped_init) + " initial points dropped" : "") +
           (r.thinned ? ", " + std::to_string(r.thinned) + " seeds thinned" : ""));
}

}  // namespace pm

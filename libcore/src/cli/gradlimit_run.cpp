#include "pm/cli/gradlimit_run.h"

#include <algorithm>
#include <sstream>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/gradlimit.h"

namespace pm {

void add_gradlimit_options(CLI::App& app, GradLimitRun& cfg) {
  app.add_option("input", cfg.input, "Sizing field h, float voxels, world units")->required();
  app.add_option("output", cfg.output, "Limited sizing field (format by extension)")->required();
  app.add_option("--delta", cfg.params.delta, "Gradient bound |grad h| <= delta, dimensionless (> 0)")
      ->capture_default_str();
  app.add_option("--tolerance", cfg.params.tolerance,
                 "upwind: stop when the largest relative change per sweep is below this")
      ->capture_default_str();
  app.add_option("--method", cfg.method,
                 "propagate (one ordered pass, exact 26-neighbour bound) or upwind "
                 "(Persson's explicit iteration; slow, for reference)")
      ->capture_default_str();
  app.add_option("--far-field", cfg.far_field,
                 "flat: h stops growing at the largest value an input voxel can get (limited among the input "
                 "voxels alone; plus delta x 2 voxel diagonals), so every voxel below that, every input voxel "
                 "among them, is as with grow, and the far field is not filled (several times faster around a "
                 "surface; --stats parameters.cap); grow: h + delta x distance everywhere")
      ->check(CLI::IsMember({"flat", "grow"}))
      ->capture_default_str();
  app.add_flag("--nan-unknown", cfg.params.nonfinite_unknown,
               "Treat NaN/Inf voxels as unknown instead of refusing them");
  app.add_option("--inward", cfg.inward,
                 "Interior sizing for volume packing: keep h only within --band of this "
                 "surface's vertices (.ply .off .obj .stl .vtk .vtp .mesh, world units) and "
                 "grow it inward from there with --delta");
  app.add_option("--band", cfg.band, "With --inward: world units (default 2 voxels of the smallest spacing)");
  cfg.max_size_opt =
      app.add_option("--max-size", cfg.max_size,
                     "With --inward: cap on h, world units (> 0; default: the largest h near the surface)");
  app.add_flag("--gzip", cfg.gzip,
               "Compress the output where the format allows (a dense float field shrinks by "
               "only ~30% and gzip takes seconds on 256^3; off by default)");
}

void run_gradlimit(GradLimitRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& method = cfg.method;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& inward = cfg.inward;
  [[maybe_unused]] auto& band = cfg.band;
  [[maybe_unused]] auto& max_size = cfg.max_size;
  [[maybe_unused]] auto& max_size_opt = cfg.max_size_opt;
  [[maybe_unused]] auto& gzip = cfg.gzip;
  pm::check_output_path(out, pm::OutputKind::volume, "output");
  auto& st = pm::stats();
  if (method == "propagate")
    p.method = pm::GradLimitMethod::propagate;
  else if (method == "upwind")
    p.method = pm::GradLimitMethod::upwind;
  else
    throw pm::UsageError("--method \"" + method + "\"; expected propagate or upwind");
  if (!(p.delta > 0)) {
    std::ostringstream m;
    m << "--delta " << p.delta << "; expected > 0 (e.g. 0.3)";
    throw pm::UsageError(m.str());
  }
  p.flat_far_field = cfg.far_field == "flat";
  if (inward.empty() && (band != 0 || max_size != 0))
    throw pm::UsageError("--band and --max-size need --inward SURFACE");
  if (!inward.empty() && band < 0)
    throw pm::UsageError("--band " + std::to_string(band) + "; expected > 0 (world units)");
  if (max_size_opt->count() && !(max_size > 0))
    throw pm::UsageError("--max-size " + std::to_string(max_size) + "; expected > 0 (world units)");
  st["inputs"] = inward.empty() ? pm::Json{in} : pm::Json{in, inward};
  st["parameters"] = {{"delta", p.delta},
                      {"tolerance", p.tolerance},
                      {"method", method},
                      {"nan_unknown", p.nonfinite_unknown},
                      {"far_field", cfg.far_field},
                      {"gzip", gzip}};
  const pm::Volume h = pm::read_volume(in);
  pm::GradLimitResult r;
  {
    pm::ScopedStage stage("gradlimit");
    try {
      if (inward.empty()) {
        r = pm::gradient_limit(h, p);
        st["parameters"]["cap"] = r.cap;
      } else {
        const pm::Mesh surface = pm::read_mesh(inward);
        if (surface.vertices.empty()) throw pm::InputError(pm::quote(inward) + " has no vertices");
        const pm::Geometry& g = h.geometry();
        if (band == 0) band = 2 * std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
        st["parameters"]["band"] = band;
        st["parameters"]["max_size"] = max_size;
        r = pm::interior_sizing(h, surface.vertices, band, p.delta, max_size);
        st["parameters"]["cap"] = r.cap;
        pm::info("interior sizing capped at " + std::to_string(r.cap) + " world units");
      }
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
  }
  pm::VolumeWriteParams wp;
  wp.compress = gzip;
  pm::write_volume(r.h, out, wp);
  st["outputs"] = {out};
  st["counts"] = {{"voxels", h.count()},  {"known", r.known},           {"unknown", r.unknown},
                  {"lowered", r.lowered}, {"iterations", r.iterations}, {"max_slope_over_delta", r.max_slope_ratio}};
  pm::info(std::to_string(r.lowered) + " of " + std::to_string(r.known) + " known voxels lowered, " +
           std::to_string(r.unknown) + " unknown voxels extended");
}

}  // namespace pm

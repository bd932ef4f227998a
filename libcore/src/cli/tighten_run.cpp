#include "pm/cli/tighten_run.h"

#include <type_traits>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/tighten.h"

namespace pm {

void add_tighten_options(CLI::App& app, TightenRun& cfg) {
  app.add_option("input", cfg.input, "Binary mask volume (label map with --per-label)")->required();
  app.add_option("output", cfg.output,
                 "Signed distance volume (format by extension); with --per-label a pattern "
                 "where %d becomes each label, e.g. out/sdf_%d.nrrd")
      ->required();
  app.add_flag("--per-label", cfg.per_label,
               "Chapter 6: input is a label map; tighten every label (0 included) as its own mask, all on "
               "the input grid (upsampled by --upsample; the border is extended by replicating labels, not "
               "treated as an interface) and write one signed distance per label (negative inside)");
  app.add_option("-r,--radius", cfg.radius,
                 "Tightening radius R, world units (> 0); auto = the largest voxel spacing of the input (from "
                 "its header, so anisotropic slices are smoothed), divided by the automatic --upsample K "
                 "on tiny volumes")
      ->capture_default_str();
  app.add_option("--upsample", cfg.upsample,
                 "Resample the mask K (1-8) times finer first (trilinear), for R below a voxel or so; output "
                 "spacing h/K; auto = 1, or on a volume with fewer than 8 voxels along an axis the smallest K "
                 "giving 16 (at most 8)")
      ->capture_default_str();
  app.add_option("--iterations", cfg.params.max_iterations,
                 "Most flow steps; 0 = automatic (until converged, at "
                 "most 20 (R/h)^2 + 160)")
      ->capture_default_str();
  app.add_option("--tolerance", cfg.params.tolerance,
                 "Converged when no node of the zero set moves more than this in a step, or when it moved "
                 "less than half of this in the mean over a --reinit cycle, voxels")
      ->capture_default_str();
  app.add_option("--reinit", cfg.params.reinit_every,
                 "Every N flow steps, re-distance the flowing field if |grad phi| is off 1 by > 0.5 at more than 5% of the zero-set nodes")
      ->capture_default_str();
  app.add_option("--outside-band", cfg.outside_band,
                 "Outside the material, accurate distances only within W of the surface (world units) and "
                 "about a voxel off farther out; faster where materials are much smaller than the grid. Only "
                 "where the outside reaches the grid's faces (a bounded outside keeps its exact depth); the "
                 "inside is always accurate. 0 = accurate everywhere; auto = 6 voxel diagonals of the output "
                 "grid (what medialaxis --side inside reads outside). Example: --outside-band 20")
      ->capture_default_str();
  app.add_flag("--positive-inside", cfg.params.positive_inside, "Write positive inside, negative outside (Chapter 6)");
  app.add_flag("--gzip", cfg.gzip,
               "Compress the output where the format allows (float distances shrink by only "
               "~10% and gzip takes seconds on 256^3; off by default)");
}

namespace {
// v from all of s (std::stod / std::stoi); false when s is not one number.
template <class T>
bool parse_whole(const std::string& s, T& v) {
  std::size_t used = 0;
  try {
    if constexpr (std::is_integral_v<T>)
      v = std::stoi(s, &used);
    else
      v = std::stod(s, &used);
  } catch (const std::exception&) {
    return false;
  }
  return used == s.size();
}

// The warning of a run that hit the step cap; the mean move of the zero set
// only when a whole re-distancing cycle ran.
std::string not_converged_note(const TightenResult& r, const TightenParams& p) {
  std::string s = "not converged after " + std::to_string(r.iterations) + " steps (last move " +
                  std::to_string(r.last_change) + " voxels";
  if (r.iterations >= p.reinit_every) s += ", mean over the last cycle " + std::to_string(r.cycle_change);
  return s + "); raise --iterations";
}
}  // namespace

void run_tighten(TightenRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& per_label = cfg.per_label;
  [[maybe_unused]] auto& radius = cfg.radius;
  [[maybe_unused]] auto& upsample = cfg.upsample;
  [[maybe_unused]] auto& gzip = cfg.gzip;
  pm::check_output_path(out, pm::OutputKind::volume, "output");
  auto& st = pm::stats();
  double r_given = 0;
  int k_given = 0;
  if (radius != "auto") {
    if (!parse_whole(radius, r_given))
      throw pm::UsageError("--radius " + radius + "; expected a number > 0 (world units) or auto");
    if (!(r_given > 0))
      throw pm::UsageError("tighten: radius " + std::to_string(r_given) +
                           " is invalid; expected > 0 (world units) or auto");
  }
  if (upsample != "auto") {
    if (!parse_whole(upsample, k_given))
      throw pm::UsageError("--upsample " + upsample + "; expected an integer 1 to 8 or auto");
    if (k_given < 1 || k_given > 8)
      throw pm::UsageError("tighten: upsample " + std::to_string(k_given) + " is invalid; expected 1 to 8 or auto");
  }
  double band_given = 0;
  if (cfg.outside_band != "auto") {
    if (!parse_whole(cfg.outside_band, band_given) || !(band_given >= 0) || !std::isfinite(band_given))
      throw pm::UsageError("--outside-band " + cfg.outside_band + "; expected a number >= 0 (world units) or auto");
  }
  if (!pm::is_volume_path(out)) throw pm::UsageError("output " + pm::quote(out) + ": unknown volume extension");
  const pm::Volume input = pm::read_volume(in);
  const pm::TightenDefaults d = pm::tighten_defaults(input, r_given, k_given);
  p.radius = d.radius;
  p.upsample = d.upsample;
  p.outside_band = band_given;
  if (cfg.outside_band == "auto") p.outside_band = pm::tighten_outside_band_auto(input.geometry(), p.upsample);
  if (radius == "auto" || upsample == "auto") {
    std::string why;
    if (radius == "auto") why = "radius from the header's largest spacing";
    if (upsample == "auto" && p.upsample > 1) why += std::string(why.empty() ? "" : ", ") + "tiny volume upsampled";
    pm::info("radius " + std::to_string(p.radius) + " (world units), upsample " + std::to_string(p.upsample) +
             (why.empty() ? "" : " (" + why + ")"));
  }
  st["inputs"] = {in};
  st["parameters"] = {{"radius", p.radius},
                      {"upsample", p.upsample},
                      {"iterations", p.max_iterations},
                      {"tolerance", p.tolerance},
                      {"reinit", p.reinit_every},
                      {"positive_inside", p.positive_inside},
                      {"outside_band", p.outside_band},
                      {"gzip", gzip}};
  pm::VolumeWriteParams wp;
  wp.compress = gzip;
  if (per_label) {
    const auto pct = out.find("%d");
    if (pct == std::string::npos || out.find("%d", pct + 1) != std::string::npos)
      throw pm::UsageError("output " + pm::quote(out) + ": with --per-label expected a pattern with one %d");
    const pm::Volume& labels = input;
    pm::Json per = pm::Json::object(), outputs = pm::Json::array();
    pm::ScopedStage stage("tighten");
    try {
      pm::tighten_labels(labels, p, [&](int label, pm::TightenResult&& r) {
        const std::string path = out.substr(0, pct) + std::to_string(label) + out.substr(pct + 2);
        if (r.radius < r.requested_radius) pm::warn("label " + std::to_string(label) + ": " + pm::tighten_radius_note(r));
        if (!r.converged) pm::warn("label " + std::to_string(label) + ": " + not_converged_note(r, p));
        pm::info("label " + std::to_string(label) + ": " + std::to_string(r.iterations) + " flow steps -> " + path);
        pm::write_volume(r.distance, path, wp);
        outputs.push_back(path);
        per[std::to_string(label)] = {{"inside_voxels", r.inside_voxels}, {"mortar_nodes", r.mortar_nodes},
                                      {"iterations", r.iterations},       {"reinits", r.reinits},
                                      {"converged", r.converged},         {"last_change_voxels", r.last_change},
                                      {"cycle_change_voxels", r.cycle_change}, {"radius", r.radius}};
      });
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
    st["outputs"] = outputs;
    st["counts"] = {{"labels", per.size()}, {"per_label", per}};
    return;
  }
  const pm::Volume& mask = input;
  pm::TightenResult r;
  {
    pm::ScopedStage stage("tighten");
    try {
      r = pm::tighten(mask, p);
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
  }
  if (r.pad > 0)
    pm::warn("the mask comes within R + 3 voxels of the border: padded by " + std::to_string(r.pad) +
             " voxels on every side (output origin moved)");
  if (r.radius < r.requested_radius) pm::warn(pm::tighten_radius_note(r));
  if (!r.converged) pm::warn(not_converged_note(r, p));
  pm::info(std::to_string(r.iterations) + " flow steps over " + std::to_string(r.mortar_nodes) + " mortar nodes");
  pm::write_volume(r.distance, out, wp);
  st["outputs"] = {out};
  st["counts"] = {{"inside_voxels", r.inside_voxels},   {"mortar_nodes", r.mortar_nodes},
                  {"iterations", r.iterations},         {"reinits", r.reinits},
                  {"converged", r.converged},           {"pad", r.pad},
                  {"last_change_voxels", r.last_change}, {"cycle_change_voxels", r.cycle_change},
                  {"radius", r.radius}};
}

}  // namespace pm

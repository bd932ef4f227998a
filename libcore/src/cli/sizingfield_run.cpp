#include "pm/cli/sizingfield_run.h"

#include <sstream>
#include <vector>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/medialaxis.h"
#include "pm/volume/sizingfield.h"

namespace pm {

void add_sizingfield_options(CLI::App& app, SizingFieldRun& cfg) {
  app.add_option("--sdf", cfg.sdfs, "Signed distance volume (negative inside); repeat per surface")->required();
  app.add_option("--ma", cfg.mas, "Medial-axis points of that surface (.ply from medialaxis); one per --sdf")
      ->required();
  app.add_option("-o,--output", cfg.output, "Sizing field volume (float, world units, 0 = unknown)")->required();
  app.add_option("--eps", cfg.params.eps, "epsilon of the eps-sampling (> 0); h0 = 2 eps min(LFS, 1/|k|)")
      ->capture_default_str();
  app.add_option("--hmin", cfg.params.hmin, "Lower bound on h, world units (Chapter 6: the tightening radius)")
      ->capture_default_str();
  app.add_option("--band", cfg.params.band, "Half-width of the band of known nodes around the surface, voxels")
      ->capture_default_str();
  app.add_option("--contraction", cfg.params.contraction, "Distance contraction g (>= 1): h is divided by it")
      ->capture_default_str();
  app.add_flag("--no-contract", cfg.no_contract, "Do not divide by the contraction g");
  app.add_flag("--at-node", cfg.at_node,
               "Evaluate LFS and curvature at the grid node, not at its closest "
               "surface point");
  app.add_option("--lfs", cfg.lfs_out, "Also write the local feature size volume (world units, 0 = unknown)");
  app.add_flag("--gzip", cfg.gzip,
               "Compress the outputs where the format allows (a float field: gzip costs more time than the "
               "disk it saves; off by default, as in tighten and gradlimit)");
}

void run_sizingfield(SizingFieldRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& sdfs = cfg.sdfs;
  [[maybe_unused]] auto& mas = cfg.mas;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& lfs_out = cfg.lfs_out;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& no_contract = cfg.no_contract;
  [[maybe_unused]] auto& at_node = cfg.at_node;
  pm::check_output_path(out, pm::OutputKind::volume, "--output");
  pm::check_output_path(lfs_out, pm::OutputKind::volume, "--lfs");
  auto& st = pm::stats();
  p.contract = !no_contract;
  if (!(p.eps > 0)) throw pm::UsageError("--eps " + pm::format_number(p.eps) + "; expected > 0");
  if (!(p.hmin >= 0)) throw pm::UsageError("--hmin " + pm::format_number(p.hmin) + "; expected >= 0 (world units)");
  if (!(p.band > 0)) throw pm::UsageError("--band " + pm::format_number(p.band) + "; expected > 0 voxels");
  if (!(p.contraction >= 1))
    throw pm::UsageError("--contraction " + pm::format_number(p.contraction) + "; expected >= 1");
  p.at_foot_point = !at_node;
  st["inputs"] = {{"sdf", sdfs}, {"ma", mas}};
  st["parameters"] = {{"eps", p.eps},           {"hmin", p.hmin},
                      {"band", p.band},         {"contraction", p.contraction},
                      {"contract", p.contract}, {"at_foot_point", p.at_foot_point}};
  if (sdfs.size() != mas.size())
    throw pm::UsageError("got " + std::to_string(sdfs.size()) + " --sdf and " + std::to_string(mas.size()) +
                         " --ma; expected one medial axis per distance volume");
  // Read side by side; the error reported is the first a loop in order meets.
  std::vector<pm::Volume> volumes(sdfs.size());
  std::vector<std::vector<pm::Vec3>> axes(sdfs.size());
  pm::parallel_tasks(sdfs.size(), [&](std::size_t s) {
    volumes[s] = pm::read_volume(sdfs[s]);
    pm::require_distance_volume(volumes[s], pm::quote(sdfs[s]));
    axes[s] = pm::read_mesh(mas[s]).vertices;
    if (axes[s].empty())
      throw pm::InputError(pm::quote(mas[s]) + ": no medial-axis points; expected the output of medialaxis for " +
                           pm::quote(sdfs[s]));
  });
  std::vector<pm::SizingSurface> surfaces;
  for (std::size_t s = 0; s < sdfs.size(); ++s) surfaces.push_back({volumes[s], axes[s], sdfs[s]});
  pm::SizingFieldResult r;
  {
    pm::ScopedStage stage("sizingfield");
    r = pm::sizing_field(surfaces, p);
  }
  pm::info(std::to_string(r.known) + " known nodes, h " + std::to_string(r.h_lo) + " to " + std::to_string(r.h_hi) +
           ", LFS " + std::to_string(r.lfs_lo) + " to " + std::to_string(r.lfs_hi) + " (world units)");
  pm::VolumeWriteParams wp;
  wp.compress = cfg.gzip;
  pm::write_volume(r.h, out, wp);
  if (!lfs_out.empty()) pm::write_volume(r.lfs, lfs_out, wp);
  st["outputs"] = lfs_out.empty() ? pm::Json{out} : pm::Json{out, lfs_out};
  st["counts"] = {{"known", r.known},
                  {"curvature_limited", r.curvature_limited},
                  {"hmin_limited", r.hmin_limited},
                  {"h_min", r.h_lo},
                  {"h_max", r.h_hi},
                  {"lfs_min", r.lfs_lo},
                  {"lfs_max", r.lfs_hi}};
}

}  // namespace pm

#include "pm/cli/medialaxis_run.h"

#include <cmath>
#include <sstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/run_tool.h"
#include "pm/field/distance.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/medialaxis.h"

namespace pm {

void add_medialaxis_options(CLI::App& app, MedialAxisRun& cfg) {
  app.add_option("input", cfg.input, "Signed distance volume (negative inside)")->required();
  app.add_option("output", cfg.output, "Medial-axis points (.ply .vtp .vtk), world units")->required();
  app.add_option("--cos-alpha", cfg.params.cos_alpha,
                 "cos of the smallest turn of the characteristic that marks the "
                 "medial axis, in (-1, 1); dimensionless")
      ->capture_default_str();
  app.add_option("--volume", cfg.volume, "Also write a uint8 volume with 1 at the node nearest each point");
  app.add_option("--side", cfg.side, "Which medial axis: inside, outside or both")
      ->check(CLI::IsMember({"inside", "outside", "both"}))
      ->capture_default_str();
  app.add_option("--iso", cfg.iso,
                 "The input is a grey-level volume: use the signed distance to its level set "
                 "at this value (input units) instead");
  app.add_option("--inside", cfg.inside,
                 "With --iso: which values are inside, below (F < iso, the default) or "
                 "above (CT bone)")
      ->check(CLI::IsMember({"below", "above"}))
      ->capture_default_str();
  app.add_option("--sdf-out", cfg.sdf_out, "With --iso: also write that signed distance volume (for sizingfield)");
  app.add_option("--foot-iterations", cfg.params.foot_iterations, "Tangent-plane refinements of each foot point")
      ->capture_default_str();

  app.add_flag("--lfs-only", cfg.lfs_only,
               "Keep only the medial-axis points that can be the nearest one of some surface point, "
               "for sizingfield: those within twice the depth of the shallower side (the one that "
               "stays inside the grid) plus two voxel diagonals, world units. The local feature size "
               "is the same; the far medial axis (deep in a large background) is skipped");
  pm::add_frame_option(app, cfg.frame);
}

void run_medialaxis(MedialAxisRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& volume = cfg.volume;
  [[maybe_unused]] auto& side = cfg.side;
  [[maybe_unused]] auto& inside = cfg.inside;
  [[maybe_unused]] auto& sdf_out = cfg.sdf_out;
  [[maybe_unused]] auto& iso = cfg.iso;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& frame = cfg.frame;
  pm::check_output_path(out, pm::OutputKind::points, "output");
  pm::check_output_path(volume, pm::OutputKind::volume, "--volume");
  pm::check_output_path(sdf_out, pm::OutputKind::volume, "--sdf-out");
  auto& st = pm::stats();
  st["inputs"] = {in};
  p.inside = side != "outside";
  p.outside = side != "inside";
  st["parameters"] = {{"cos_alpha", p.cos_alpha}, {"side", side}, {"foot_iterations", p.foot_iterations}};
  if (!(p.cos_alpha > -1 && p.cos_alpha < 1))
    throw pm::UsageError("--cos-alpha " + pm::format_number(p.cos_alpha) + "; expected a value in (-1, 1)");
  if (p.foot_iterations < 0)
    throw pm::UsageError("--foot-iterations " + std::to_string(p.foot_iterations) + "; expected >= 0");
  if (!sdf_out.empty() && std::isnan(iso)) throw pm::UsageError("--sdf-out needs --iso");
  pm::Volume sdf = pm::read_volume(in);
  if (!std::isnan(iso)) {
    pm::ScopedStage stage("distance");
    pm::DistanceParams dp;
    dp.iso = iso;
    try {
      sdf = pm::signed_distance(sdf, dp);
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
    if (inside == "above") {
      float* v = sdf.data<float>();
      for (std::size_t c = 0; c < sdf.count(); ++c) v[c] = -v[c];
    }
    st["parameters"]["iso"] = iso;
    st["parameters"]["inside"] = inside;
  }
  if (std::isnan(iso)) {  // a mask or a grey-level scan given as it is: say what to do
    try {
      pm::require_distance_volume(sdf, "medial_axis: input");
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what() + "; tighten a mask first, or give --iso for a grey-level volume");
    }
  }
  if (cfg.lfs_only) {
    p.max_distance = pm::medial_axis_lfs_bound(sdf);
    st["parameters"]["max_distance"] = std::isfinite(p.max_distance) ? pm::Json(p.max_distance) : pm::Json("all");
    pm::info(std::isfinite(p.max_distance)
                 ? "--lfs-only: medial-axis points within " + pm::format_number(p.max_distance) +
                       " (world units) of the surface"
                 : "--lfs-only: both sides reach the grid's faces; every medial-axis point is kept");
  }
  pm::MedialAxisResult r;
  {
    pm::ScopedStage stage("medialaxis");
    try {
      r = pm::medial_axis(sdf, p);
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
  }
  if (r.points.vertices.empty()) pm::warn("no medial-axis points found");
  pm::info(std::to_string(r.points.vertices.size()) + " medial-axis points (" + std::to_string(r.inner) + " inner, " +
           std::to_string(r.outer) + " outer); " + std::to_string(r.nodes_refined) +
           " foot points refined on the field");
  pm::write_mesh(r.points, out, {true, frame});
  if (!volume.empty()) pm::write_volume(pm::mark_points(sdf, r.points.vertices), volume);
  if (!sdf_out.empty()) {
    pm::VolumeWriteParams wp;
    wp.compress = false;  // float distances barely compress; gzip costs seconds on 256^3
    pm::write_volume(sdf, sdf_out, wp);
  }
  st["outputs"] = pm::Json{out};
  if (!volume.empty()) st["outputs"].push_back(volume);
  if (!sdf_out.empty()) st["outputs"].push_back(sdf_out);
  st["counts"] = {{"points", r.points.vertices.size()},
                  {"inner", r.inner},
                  {"outer", r.outer},
                  {"nodes_refined", r.nodes_refined},
                  {"nodes", sdf.count()}};
}

}  // namespace pm

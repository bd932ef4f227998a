#include "pm/cli/volconv_run.h"

#include <cmath>
#include <iostream>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/field/distance.h"
#include "pm/field/materials.h"
#include "pm/field/mesh_sdf.h"
#include "pm/field/volume_field.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/labels.h"

namespace pm {
namespace {

pm::Json volume_info(const pm::Volume& v, const std::string& path) {
  pm::Json j;
  const auto& g = v.geometry();
  j["file"] = path;
  j["dims"] = {v.dims().nx, v.dims().ny, v.dims().nz};
  j["type"] = pm::voxel_type_name(v.type());
  j["spacing"] = {g.spacing(0), g.spacing(1), g.spacing(2)};
  j["origin"] = {g.origin.x, g.origin.y, g.origin.z};
  pm::Json dirs = pm::Json::array();
  for (int a = 0; a < 3; ++a) {
    const pm::Vec3 c = g.directions.column(a);
    dirs.push_back({c.x, c.y, c.z});
  }
  j["space_directions"] = dirs;
  // libcore's world frame (pm/base/volume.h) and the frame the file was in.
  const pm::FrameSource& f = v.frame_source();
  j["frame"] = "LPS";
  j["source_format"] = f.format;
  j["source_space"] = f.space;
  if (!f.note.empty()) j["frame_note"] = f.note;
  const pm::Box b = v.world_bounds();
  j["world_bounds"] = {{b.lo.x, b.lo.y, b.lo.z}, {b.hi.x, b.hi.y, b.hi.z}};
  const pm::ValueRange r = pm::value_range(v);
  double sum = 0;
  for (std::size_t i = 0; i < v.count(); ++i) sum += v.get(i);
  j["mean"] = sum / double(v.count());
  j["min"] = r.lo;
  j["max"] = r.hi;
  if (pm::is_integer(v.type())) {
    try {
      pm::Json labels = pm::Json::object();
      for (const auto& [l, c] : pm::label_counts(v, 4096)) labels[std::to_string(l)] = c;
      j["labels"] = labels;
    } catch (const pm::InputError&) {
      j["labels"] = "more than 4096 distinct values (not a label map)";
    }
  }
  return j;
}

}  // namespace

void add_volconv_options(CLI::App& app, VolConvRun& cfg) {
  app.add_option("input", cfg.input, "Input volume, or mesh with --sdf")->required();
  app.add_option("output", cfg.output, "Output volume (format by extension)");
  app.add_flag("--info", cfg.info,
               "Print the input's header as JSON on stdout (dims, spacing, origin and "
               "directions in LPS world units, the file's own frame, type, min/max, label "
               "counts for integer volumes)");
  app.add_flag("--sdf", cfg.sdf, "Input is a closed triangle mesh: write its signed distance volume");
  app.add_option("--voxel", cfg.sp.voxel, "With --sdf: voxel size, world units (mesh units)");
  app.add_option("--band", cfg.sp.band,
                 "With --sdf: narrow band half-width in voxels; 0 = exact distance in the "
                 "whole box")
      ->capture_default_str();
  app.add_option("--padding", cfg.sp.padding, "With --sdf: voxels of margin around the mesh")->capture_default_str();
  cfg.thr = app.add_option("--threshold", cfg.distance_iso,
                           "Write a uint8 mask (1 = material) of the side of F = ISO given by --inside");
  cfg.dist = app.add_option("--distance", cfg.distance_iso,
                            "Write the signed distance (world units, negative inside) to the level set "
                            "F = ISO of the input volume (grey values, masks: 0.5)");
  app.add_option("--inside", cfg.inside,
                 "With --distance/--threshold: the material is below ISO (distance fields), above (masks, CT) or auto "
                 "(the side the volume's corners are not on)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "below", "above"}));
  app.add_option("--labels", cfg.labels, "Write a uint8 mask (1/0) of these labels, e.g. \"2,41\" or \"2-5\"");
  app.add_option("--merge", cfg.merge, "Relabel before anything else: \"1,2:1 3,4:2\" maps 1,2 to 1 and 3,4 to 2");
  app.add_flag("--argmax", cfg.argmax,
               "Input is a material set \"L1=a.nrrd,L2=+b.nrrd,...\" (see tetlabel --materials; +: positive "
               "inside): write the label map of the material with the largest indicator at each voxel node "
               "(int32, the first volume's grid)");
  app.add_option("--pad", cfg.pad,
                 "Last (before --type): grow the grid by N (0-4096) voxels on every side (the origin "
                 "moves so every voxel keeps its world position), e.g. so that materials touching the "
                 "volume border get a surface there; auto[:N] = N (default 3) voxels on a label map "
                 "whose border holds more than one label, else none")
      ->capture_default_str();
  app.add_option("--pad-value", cfg.pad_value,
                 "Value of the padding voxels: a number, \"new\" = one more than the largest label "
                 "(a new outside material for a label map), or \"auto\" = the label holding more than half "
                 "of the border voxels (the background of a cut scan), else new")
      ->capture_default_str();
  app.add_option("--min-voxels", cfg.min_voxels,
                 "After --merge: drop labels with fewer than N voxels; their voxels join the most common "
                 "neighbouring label (0 = keep all)")
      ->capture_default_str();
  app.add_flag("--allow-nonfinite", cfg.allow_nonfinite, "Copy NaN/Inf voxels instead of refusing the input");
  app.add_flag("--no-gzip", cfg.no_gzip,
               "Write the output uncompressed (NRRD, MHA; default: gzip where the format allows). For a pipeline's "
               "intermediate files: a 500x470x136 label map takes 0.07 s to deflate and as long to inflate");
  app.add_option("--type", cfg.type,
                 "Convert the voxel type: uint8 int8 uint16 int16 uint32 int32 float double, or smallest = the "
                 "smallest integer type holding every value (label maps: uint8 for labels 0-255)");
}

void run_volconv(VolConvRun& cfg, const CommonFlags& flags, const CLI::App& app) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& labels = cfg.labels;
  [[maybe_unused]] auto& merge = cfg.merge;
  [[maybe_unused]] auto& type = cfg.type;
  [[maybe_unused]] auto& inside = cfg.inside;
  [[maybe_unused]] auto& distance_iso = cfg.distance_iso;
  [[maybe_unused]] auto& info = cfg.info;
  [[maybe_unused]] auto& sdf = cfg.sdf;
  [[maybe_unused]] auto& allow_nonfinite = cfg.allow_nonfinite;
  [[maybe_unused]] auto& sp = cfg.sp;
  [[maybe_unused]] auto& thr = cfg.thr;
  [[maybe_unused]] auto& dist = cfg.dist;
  [[maybe_unused]] auto& argmax = cfg.argmax;
  [[maybe_unused]] auto& pad = cfg.pad;
  [[maybe_unused]] auto& pad_value = cfg.pad_value;
  [[maybe_unused]] auto& min_voxels = cfg.min_voxels;
  auto& st = pm::stats();
  st["inputs"] = {in};
  if (info) {
    const pm::Volume v = pm::read_volume(in);
    std::cout << volume_info(v, in).dump(2) << "\n";
    return;
  }
  if (out.empty()) throw pm::UsageError("an output file is required (or --info)");
  pm::check_output_path(out, pm::OutputKind::volume, "output");
  // --pad N | auto | auto:N
  std::size_t pad_voxels = 0;
  const bool pad_auto = pad.rfind("auto", 0) == 0;
  {
    std::string n = pad_auto ? pad.substr(4) : pad;
    if (pad_auto && !n.empty()) n = n[0] == ':' ? n.substr(1) : std::string("x");
    if (pad_auto && n.empty()) n = std::to_string(pm::kAutoPadVoxels);
    std::size_t pos = 0;
    long v = -1;
    try {
      v = std::stol(n, &pos);
    } catch (const std::exception&) {
      pos = 0;
    }
    if (pos == 0 || pos != n.size() || v < 0 || v > 4096 || (pad_auto && v == 0))
      throw pm::UsageError("--pad \"" + pad + "\": expected a voxel count 0-4096, auto or auto:N (N 1-4096)");
    pad_voxels = std::size_t(v);
  }
  pm::Volume v;
  if (argmax) {
    const pm::MaterialSet ms = pm::load_materials(in, pm::KernelType::catmull_rom);
    // The grid of the first volume named in the spec.
    std::string first = in.substr(in.find('=') + 1);
    first = first.substr(0, first.find(','));
    first.erase(0, first.find_first_not_of(" \t+"));
    first.erase(first.find_last_not_of(" \t") + 1);
    const pm::Volume g = pm::read_volume(first);
    v = pm::argmax_labels(ms, g);
    st["parameters"] = {{"argmax", in}};
  } else if (sdf) {
    if (!(sp.voxel > 0)) throw pm::UsageError("--sdf needs --voxel V with V > 0 (world units)");
    const pm::Mesh m = pm::read_mesh(in);
    pm::ScopedStage stage("sdf");
    try {
      v = pm::mesh_to_sdf(m, sp);
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": " + e.what());
    }
    st["parameters"] = {{"voxel", sp.voxel}, {"band", sp.band}, {"padding", sp.padding}};
    pm::info("signed distance " + std::to_string(v.dims().nx) + "x" + std::to_string(v.dims().ny) + "x" +
             std::to_string(v.dims().nz) + " voxels");
  } else {
    v = pm::read_volume(in);
    if (!allow_nonfinite) pm::require_finite(v, pm::quote(in));
    if (!merge.empty()) {
      const auto rules = pm::parse_merge_spec(merge);
      pm::require_labels(v, pm::quote(in));
      v = pm::merge_labels(v, rules);
    }
    if (min_voxels > 0) {
      pm::require_labels(v, pm::quote(in));
      std::vector<std::int64_t> dropped;
      try {
        v = pm::drop_small_labels(v, min_voxels, &dropped);
      } catch (const pm::InputError& e) {
        throw pm::InputError(pm::quote(in) + ": " + e.what());
      }
      std::string list;
      for (auto l : dropped) list += " " + std::to_string(l);
      if (!dropped.empty())
        pm::info("dropped " + std::to_string(dropped.size()) + " label(s) below " + std::to_string(min_voxels) +
                 " voxels:" + list);
      st["dropped_labels"] = dropped;
    }
    if (!labels.empty()) v = pm::label_mask(v, pm::parse_label_list(labels), pm::quote(in));
    if (thr->count() > 0 && dist->count() > 0) throw pm::UsageError("give only one of --threshold and --distance");
    if (thr->count() > 0) {
      bool below = inside == "below";
      if (inside == "auto") below = pm::material_below_iso(pm::VolumeField(v, {}, in), distance_iso);
      pm::Volume m(pm::VoxelType::u8, v.dims(), v.geometry());
      std::size_t n = 0;
      for (std::size_t i = 0; i < v.count(); ++i) {
        const bool on = below ? v.get(i) < distance_iso : v.get(i) > distance_iso;
        m.set(i, on ? 1.0 : 0.0);
        n += on;
      }
      if (n == 0 || n == v.count())
        throw pm::InputError(pm::quote(in) + ": no surface: every voxel is on one side of " +
                             std::to_string(distance_iso) + "; expected an isovalue inside the value range");
      v = std::move(m);
      st["parameters"] = {{"threshold", distance_iso}, {"inside", below ? "below" : "above"}};
    }
    if (dist->count() > 0) {
      pm::ScopedStage stage("distance");
      bool below = inside == "below";
      if (inside == "auto") below = pm::material_below_iso(pm::VolumeField(v, {}, in), distance_iso);
      pm::DistanceParams dp;
      dp.iso = distance_iso;
      try {
        v = pm::signed_distance(v, dp);
      } catch (const pm::InputError& e) {
        throw pm::InputError(pm::quote(in) + ": " + e.what());
      }
      if (!below)
        for (std::size_t i = 0; i < v.count(); ++i) v.set(i, -v.get(i));
      st["parameters"] = {{"distance_iso", distance_iso}, {"inside", below ? "below" : "above"}};
    }
  }
  pm::BorderPadding border;
  if (pad_auto || pad_value == "auto") {
    try {
      border = pm::border_padding(v);  // refuses a volume that is not a label map
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": --pad auto / --pad-value auto need a label map: " + e.what());
    }
    if (pad_auto && !border.pad) pad_voxels = 0;
    st["pad_auto"] = {{"border_labels", border.border_labels}, {"padded", pad_voxels > 0}};
  }
  if (pad_voxels > 0 || (!pad_auto && app.count("--pad-value") > 0)) {
    if (pad_voxels == 0) throw pm::UsageError("--pad-value needs --pad N with N >= 1 (or --pad auto)");
    const double value = pm::pad_value_of(v, pad_value, pm::quote(in));
    if (pad_value == "auto")
      pm::info("padding by " + std::to_string(pad_voxels) + " voxels of " +
               (border.new_label ? "a new outside label " : "label ") + std::to_string(border.value) + ": " +
               std::to_string(border.border_labels) + " labels reach the volume border");
    v = pm::padded(v, pad_voxels, value);
    st["pad"] = {{"voxels", pad_voxels}, {"value", value}};
  }
  if (type == "smallest") {
    try {
      v = v.converted(pm::smallest_integer_type(v));
    } catch (const pm::InputError& e) {
      throw pm::InputError(pm::quote(in) + ": --type smallest: " + e.what());
    }
  } else if (!type.empty()) {
    v = v.converted(pm::parse_voxel_type(type));
  }
  pm::VolumeWriteParams wp;
  wp.compress = !cfg.no_gzip;
  pm::write_volume(v, out, wp);
  st["outputs"] = {out};
  st["counts"] = {{"voxels", v.count()}};
}

}  // namespace pm

#include "pm/cli/morph_run.h"

#include <sstream>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/cli/run_tool.h"
#include "pm/io/output_path.h"
#include "pm/io/volume_io.h"
#include "pm/volume/labels.h"
#include "pm/volume/morphology.h"

namespace pm {
namespace {

// "close:f4,open:f2" for every processed label, or "1=close:f4,open:f2; 3=open:f2" per label.
void parse_ops(const std::string& spec, pm::LabelMorphParams& p) {
  std::istringstream in(spec);
  std::string part;
  while (std::getline(in, part, ';')) {
    if (part.find_first_not_of(" \t") == std::string::npos) continue;
    const auto eq = part.find('=');
    if (eq == std::string::npos) {
      p.steps = pm::parse_morph_steps(part);
      continue;
    }
    const auto label = pm::parse_label_list(part.substr(0, eq));
    const auto steps = pm::parse_morph_steps(part.substr(eq + 1));
    for (auto l : label) p.per_label[l] = steps;
  }
}

pm::Json counts_json(const std::map<std::int64_t, std::size_t>& c) {
  pm::Json j = pm::Json::object();
  for (const auto& [l, n] : c) j[std::to_string(l)] = n;
  return j;
}

}  // namespace

void add_morph_options(CLI::App& app, MorphRun& cfg) {
  app.add_option("input", cfg.input, "Input mask or label map (integer values)")->required();
  app.add_option("output", cfg.output, "Output volume, same voxel type (format by extension)")->required();
  app.add_option("--op", cfg.op, "Operation: erode, dilate, open or close");
  app.add_option("--stencil", cfg.stencil, "Stencil for --op: plus, ball, cube, f1, f2, f3, f4")->capture_default_str();
  app.add_option("--iterations", cfg.iterations, "Repeat --op N times (open/close: N erosions then N dilations)")
      ->capture_default_str();
  app.add_option("--ops", cfg.ops,
                 "Operation sequence instead of --op, op:stencil[:N] left to right, e.g. "
                 "\"close:f4,open:f2\"; \"L=...\" entries (separated by ';') apply to label L");
  app.add_option("--labels", cfg.labels,
                 "Labels to process, e.g. \"1,2\" or \"0-4\", or \"all\" (every label present, 0 "
                 "included) (default: every non-zero label; others are passive: they keep what nobody claims)");
  app.add_option("--downsample", cfg.params.downsample,
                 "Integer factor K: K^3 voxels per output voxel (labels: "
                 "majority; with --grey: mean); spacing x K")
      ->capture_default_str();
  app.add_flag("--vote", cfg.params.vote, "Fill empty voxels by voting among face neighbours");
  app.add_option("--fill", cfg.params.fill, "Label of empty voxels without --vote")->capture_default_str();
  app.add_option("--min-component", cfg.params.min_component,
                 "Remove connected components (6-neighbour, voxels of one label, background included) with "
                 "fewer than N voxels after morphology and downsampling, refilling them by voting from their "
                 "neighbours (implies --vote); 0 = keep all")
      ->capture_default_str();
  app.add_flag("--no-gzip", cfg.no_gzip,
               "Write the output uncompressed (NRRD, MHA; default: gzip where the format allows), for a "
               "pipeline's intermediate files");
  app.add_flag("--grey", cfg.grey, "Grey-value input: only --downsample (block mean) is allowed");
}

void run_morph(MorphRun& cfg, const CommonFlags& flags) {
  (void)flags;
  [[maybe_unused]] auto& in = cfg.input;
  [[maybe_unused]] auto& out = cfg.output;
  [[maybe_unused]] auto& op = cfg.op;
  [[maybe_unused]] auto& stencil = cfg.stencil;
  [[maybe_unused]] auto& ops = cfg.ops;
  [[maybe_unused]] auto& labels = cfg.labels;
  [[maybe_unused]] auto& p = cfg.params;
  [[maybe_unused]] auto& iterations = cfg.iterations;
  [[maybe_unused]] auto& grey = cfg.grey;
  pm::check_output_path(out, pm::OutputKind::volume, "output");
  auto& st = pm::stats();
  if (!op.empty() && !ops.empty()) throw pm::UsageError("give either --op or --ops, not both");
  if (iterations < 1) throw pm::UsageError("--iterations " + std::to_string(iterations) + "; expected >= 1");
  if (p.downsample < 1)
    throw pm::UsageError("--downsample " + std::to_string(p.downsample) + "; expected an integer >= 1");
  if (!op.empty()) p.steps = {pm::MorphStep{pm::parse_morph_op(op), pm::parse_stencil(stencil), iterations}};
  if (!ops.empty()) parse_ops(ops, p);
  if (labels == "all")
    p.all_labels = true;
  else if (!labels.empty())
    p.labels = pm::parse_label_list(labels);
  const bool morph = !p.steps.empty() || !p.per_label.empty();
  if (!morph && p.downsample == 1 && !p.vote && p.min_component < 2)
    throw pm::UsageError("nothing to do; expected --op, --ops, --downsample K > 1, --vote or --min-component N");
  if (grey && (morph || p.vote || !labels.empty() || p.min_component > 1))
    throw pm::UsageError("--grey allows only --downsample (morphology, voting and components need a label map)");
  st["inputs"] = {in};
  st["parameters"] = {{"op", op},       {"stencil", stencil}, {"iterations", iterations},
                      {"ops", ops},     {"labels", labels},   {"downsample", p.downsample},
                      {"vote", p.vote}, {"grey", grey},       {"min_component", p.min_component}};
  const pm::Volume v = pm::read_volume(in);
  pm::Volume result;
  if (grey) {
    pm::require_finite(v, pm::quote(in));
    pm::ScopedStage stage("downsample");
    result = pm::downsample(v, p.downsample, pm::DownsampleMode::mean);
  } else {
    pm::ScopedStage stage("morphology");
    pm::LabelMorphResult r;
    try {
      pm::require_labels(v, pm::quote(in));
      r = pm::morph_labels(v, p);
    } catch (const pm::InputError& e) {
      const std::string m = e.what();
      throw pm::InputError(m.rfind(pm::quote(in), 0) == 0 ? m + "; for grey values use --grey --downsample K"
                                                          : pm::quote(in) + ": " + m);
    }
    st["counts"] = {{"labels_before", counts_json(r.counts_before)},
                    {"labels_after", counts_json(r.counts_after)},
                    {"empty", r.empty},
                    {"vote_rounds", r.vote_rounds},
                    {"components_removed", r.components_removed},
                    {"component_voxels_removed", r.component_voxels_removed}};
    pm::Json kept = pm::Json::array();
    for (const auto& k : r.kept) {
      kept.push_back({{"label", k.label}, {"stage", k.stage}, {"voxels", k.voxels}});
      const std::string why = k.stage == "morphology"   ? "the morphology would erase it"
                              : k.stage == "downsample" ? "downsampling would erase it"
                                                        : "every component of it is below --min-component";
      pm::warn("label " + std::to_string(k.label) + ": " + why + "; kept " + std::to_string(k.voxels) +
               " voxel(s) of it (" +
               (k.stage == "morphology"   ? "its input voxels, unprocessed"
                : k.stage == "downsample" ? "the block that holds most of it"
                                          : "its largest component") +
               ")");
    }
    for (auto l : r.lost)
      pm::warn("label " + std::to_string(l) +
               ": erased by downsampling; the downsampled grid has too few voxels "
               "to keep every label (use a smaller --downsample)");
    st["counts"]["kept"] = kept;
    st["counts"]["lost"] = r.lost;
    if (r.components_removed)
      pm::info("removed " + std::to_string(r.components_removed) + " components below " +
               std::to_string(p.min_component) + " voxels (" + std::to_string(r.component_voxels_removed) +
               " voxels, refilled by voting)");
    if (r.empty && !p.vote && !r.component_voxels_removed)
      pm::info(std::to_string(r.empty) + " voxels left empty were set to " + std::to_string(p.fill) +
               " (use --vote to fill them from their neighbours)");
    result = std::move(r.labels);
  }
  pm::VolumeWriteParams wp;
  wp.compress = !cfg.no_gzip;
  pm::write_volume(result, out, wp);
  st["outputs"] = {out};
  st["counts"]["voxels"] = result.count();
}

}  // namespace pm

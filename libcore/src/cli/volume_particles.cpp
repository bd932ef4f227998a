#include "pm/cli/volume_particles.h"

#include <memory>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/field/field.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/io/volume_io.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {
void run_volume(VolumeRun run) {
  if (run.fixed.empty()) throw UsageError("--volume needs --fixed SURFACE (the final surface or interface mesh)");
  if ((run.field != nullptr) == (run.materials != nullptr))
    throw UsageError("--volume needs exactly one of -i VOLUME / --implicit SPEC (one region) or --materials SPEC");
  auto& st = stats();
  st["inputs"] = {{"fixed", run.fixed}, {"sizing", run.sizing},
                  {"field", run.field ? run.field->describe() : run.materials->spec}};
  const Mesh boundary = read_mesh(run.fixed);
  if (boundary.vertices.empty()) throw InputError(quote(run.fixed) + " has no vertices; expected the surface mesh");
  std::unique_ptr<SizingField> sizing;
  if (!run.sizing.empty()) {
    sizing = std::make_unique<SizingField>(read_volume(run.sizing), run.sizing);
    run.params.sizing = sizing.get();
  }
  VolumePackResult r;
  int outside = 0;
  bool below = true;
  {
    ScopedStage stage("pack");
    if (run.field) {
      if (run.inside != "auto" && run.inside != "below" && run.inside != "above")
        throw UsageError("--inside \"" + run.inside + "\": expected below, above or auto");
      below = run.inside == "auto" ? material_below_iso(*run.field, run.iso) : run.inside == "below";
      if (below) {
        r = pack_volume(*run.field, run.iso, boundary.vertices, run.params, 1);
      } else {
        const NegatedField neg(*run.field);  // material F > iso is -F < -iso
        r = pack_volume(neg, -run.iso, boundary.vertices, run.params, 1);
      }
    } else {
      const MaterialSet ms = load_materials(*run.materials);
      outside = parse_outside_label(run.outside, ms);
      const auto la = boundary.face_ints.find("label_a"), lb = boundary.face_ints.find("label_b");
      if (la == boundary.face_ints.end() || lb == boundary.face_ints.end())
        throw InputError(quote(run.fixed) +
                         " has no face properties label_a and label_b; expected an interface mesh from "
                         "tetlabel --materials");
      std::vector<std::array<int, 2>> labels(boundary.faces.size());
      for (std::size_t f = 0; f < labels.size(); ++f) labels[f] = {la->second[f], lb->second[f]};
      r = pack_materials(ms, outside, boundary.vertices, boundary.faces, labels, run.params);
    }
  }
  Mesh out;
  out.vertices = r.points;
  out.vertex_scalars["spacing"] = r.spacing;
  std::vector<double> lab(r.labels.begin(), r.labels.end());
  out.vertex_scalars["label"] = std::move(lab);
  {
    ScopedStage stage("write");
    write_mesh(out, run.output, {true, run.frame});
  }
  st["outputs"] = {run.output};
  st["parameters"] = {{"iso", run.iso}, {"inside", below ? "below" : "above"}, {"spacing", run.params.spacing}, {"tolerance", run.params.tolerance},
                      {"max_iters", run.params.max_iters}, {"seed_clearance", run.params.seed_clearance},
                      {"outside", outside}};
  st["counts"] = {{"particles", r.points.size()}, {"fixed", r.fixed}, {"seeds", r.seeds},
                  {"iterations", r.iterations}, {"splits", r.splits}, {"deletions", r.deletions}};
  st["converged"] = r.converged;
  st["engine"] = engine_stats_json(r.stats);
  const std::string stuck = engine_failure_summary(r.stats);
  if (!stuck.empty()) warn(stuck);
  if (!r.converged)
    warn("volume packing not converged after " + std::to_string(r.iterations) +
         " iterations (--max-iters per region); the result was written anyway");
  info(std::to_string(r.points.size()) + " interior particles, " + std::to_string(r.fixed) + " fixed boundary particles");
}

}  // namespace pm

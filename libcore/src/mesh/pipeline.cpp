#include "pm/mesh/pipeline.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/base/stats.h"
#include "pm/field/distance.h"
#include "pm/field/sizing.h"
#include "pm/field/volume_field.h"
#include "pm/volume/gradlimit.h"
#include "pm/volume/labels.h"
#include "pm/volume/mcinit.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/volume/medialaxis.h"
#include "pm/volume/morphology.h"
#include "pm/sample/multiparticles.h"
#include "pm/sample/particles.h"
#include "pm/volume/sizingfield.h"
#include "pm/volume/tighten.h"

namespace pm {
namespace {

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Copy the particles' vertex scalars (junction, label_a, ...) onto a mesh
// made from them (vertex scalar "index" = particle index).
void copy_point_scalars(const Mesh& pts, Mesh& m) {
  const auto& idx = m.vertex_scalars.at("index");
  for (const auto& [name, vals] : pts.vertex_scalars) {
    if (name == "index") continue;
    std::vector<double> v(m.vertices.size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = vals[std::size_t(idx[i])];
    m.vertex_scalars[name] = std::move(v);
  }
}

// TetGen's complaints name the point set.
TetMesh delaunay_of(const std::string& what, const Mesh& pts, bool enclosed) {
  ScopedStage s("delaunay");
  try {
    return enclosed ? delaunay_enclosed(pts.vertices) : delaunay(pts.vertices);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
}

void require_particles(const Mesh& pts, const std::string& what) {
  if (pts.vertices.size() < 4)
    throw InputError(what + ": " + std::to_string(pts.vertices.size()) + " points; expected at least 4 particles");
}

// A point set as a PLY file between two tools holds it: float32 coordinates,
// normals and scalars.
// A double rounded to float, one value per call: GCC 12.2 (-O2 and above)
// SLP-vectorises `Vec3(double(float(v.x)), double(float(v.y)), ...)` and
// drops the round trip for the (x, y) pair as if it were the identity, so x
// and y were left unrounded (seen in the disassembly; this pipeline then gave
// other seeds than the Makefile's PLY files). Not inlined, nothing to pair.
[[gnu::noinline]] double as_float(double x) { return double(float(x)); }

void round_to_float(std::vector<Vec3>& vs) {
  for (Vec3& v : vs) {
    v.x = as_float(v.x);
    v.y = as_float(v.y);
    v.z = as_float(v.z);
  }
}

Mesh as_stored(Mesh m) {
  round_to_float(m.vertices);
  round_to_float(m.normals);
  for (auto& [name, vals] : m.vertex_scalars)
    for (double& x : vals) x = as_float(x);
  return m;
}

std::vector<Vec3> as_stored(const std::vector<Vec3>& pts) {
  Mesh m;
  m.vertices = pts;
  return as_stored(std::move(m)).vertices;
}

double min_spacing(const Volume& v) {
  const Geometry& g = v.geometry();
  return std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
}

// Stage runner: timing into `seconds`, a ScopedStage (stats, cancellation)
// and one step of the pipeline's progress.
class Stages {
 public:
  Stages(const std::string& label, std::size_t n, bool progress, std::map<std::string, double>& seconds)
      : seconds_(seconds), progress_(progress) {
    if (progress_) bar_.emplace(label, n);
  }
  template <class F>
  void run(const std::string& name, F&& f) {
    if (bar_) bar_->update(done_, name);
    Stopwatch sw;
    {
      ScopedStage s(name);
      f();
    }
    seconds_[name] += sw.seconds();
    ++done_;
    if (bar_) bar_->update(done_, name);
  }

 private:
  std::map<std::string, double>& seconds_;
  bool progress_;
  std::optional<Progress> bar_;
  std::size_t done_ = 0;
};

// Makefile.pipeline's check-input: a volume with one value has no surface;
// a grey-level volume needs an isovalue inside its range.
void check_surface_input(const Volume& v, bool mask, const std::optional<double>& iso, const std::string& what) {
  const ValueRange r = value_range(v);
  if (r.lo == r.hi)
    throw InputError(what + " has the value " + num(r.lo) +
                     " everywhere (an empty or all-inside volume): no surface to mesh; expected two values (mask) or "
                     "a grey-level range");
  if (!mask && !iso)
    throw UsageError(what + " is a grey-level volume (more than two values): give iso=value");
  if (!mask && !(r.lo < *iso && *iso < r.hi))
    throw InputError(what + ": isovalue " + num(*iso) + " is outside the value range [" + num(r.lo) + ", " +
                     num(r.hi) + "], so the volume is all inside or all outside: no surface to mesh; expected min < "
                     "iso < max");
}

// volconv --threshold ISO (inside auto): uint8 mask of the material side.
Volume threshold(const Volume& v, double iso, const std::string& what) {
  const bool below = material_below_iso(VolumeField(v, {}, what), iso);
  Volume m(VoxelType::u8, v.dims(), v.geometry());
  std::size_t n = 0;
  for (std::size_t i = 0; i < v.count(); ++i) {
    const bool on = below ? v.get(i) < iso : v.get(i) > iso;
    m.set(i, on ? 1.0 : 0.0);
    n += on;
  }
  if (n == 0 || n == v.count())
    throw InputError(what + ": no surface: every voxel is on one side of " + std::to_string(iso) +
                     "; expected an isovalue inside the value range");
  return m;
}

// volconv --distance ISO (inside auto): signed distance, negative inside.
Volume grey_distance(const Volume& v, double iso, const std::string& what) {
  const bool below = material_below_iso(VolumeField(v, {}, what), iso);
  DistanceParams dp;
  dp.iso = iso;
  Volume d;
  try {
    d = signed_distance(v, dp);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
  if (!below)
    for (std::size_t i = 0; i < d.count(); ++i) d.set(i, -d.get(i));
  return d;
}

// medialaxis (defaults; --side `side`) as the sizingfield tool reads it
// back; none is an error unless `may_be_empty`.
std::vector<Vec3> medial_points(const Volume& sdf, const std::string& what, bool may_be_empty = false,
                                const std::string& side = "both") {
  MedialAxisResult r;
  try {
    MedialAxisParams mp;
    mp.inside = side != "outside";
    mp.outside = side != "inside";
    r = medial_axis(sdf, mp);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
  std::vector<Vec3> pts = as_stored(r.points.vertices);
  if (pts.empty() && !may_be_empty)
    throw InputError(what + ": no medial-axis points; expected a signed distance volume with a surface");
  return pts;
}

// morph's warnings for the materials it kept against a stage (or lost).
void kept_label_warnings(const LabelMorphResult& r, std::vector<std::string>& out) {
  for (const KeptLabel& k : r.kept) {
    const std::string why = k.stage == "morphology"   ? "the morphology would erase it"
                            : k.stage == "downsample" ? "downsampling would erase it"
                                                      : "every component of it is below min_component";
    out.push_back("morph: label " + std::to_string(k.label) + ": " + why + "; kept " + std::to_string(k.voxels) +
                  " voxel(s) of it");
  }
  for (std::int64_t l : r.lost)
    out.push_back("morph: label " + std::to_string(l) +
                  ": erased by downsampling; the downsampled grid has too few voxels to keep every label");
}

}  // namespace

std::size_t drop_duplicate_points(Mesh& pts, double tol) {
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid;
  auto cell = [&](const Vec3& p, int dx, int dy, int dz) {
    const auto c = [&](double v, int d) { return std::uint64_t(std::int64_t(std::floor(v / tol)) + d) & 0x1fffff; };
    return (c(p.x, dx) << 42) | (c(p.y, dy) << 21) | c(p.z, dz);
  };
  std::vector<std::size_t> keep;
  for (std::size_t i = 0; i < pts.vertices.size(); ++i) {
    bool dup = false;
    for (int dx = -1; dx <= 1 && !dup; ++dx)
      for (int dy = -1; dy <= 1 && !dup; ++dy)
        for (int dz = -1; dz <= 1 && !dup; ++dz) {
          auto it = grid.find(cell(pts.vertices[i], dx, dy, dz));
          if (it == grid.end()) continue;
          for (std::size_t j : it->second)
            if (norm(pts.vertices[j] - pts.vertices[i]) <= tol) dup = true;
        }
    if (dup) continue;
    grid[cell(pts.vertices[i], 0, 0, 0)].push_back(i);
    keep.push_back(i);
  }
  const std::size_t dropped = pts.vertices.size() - keep.size();
  if (dropped == 0) return 0;
  Mesh out;
  for (std::size_t i : keep) {
    out.vertices.push_back(pts.vertices[i]);
    if (pts.has_normals()) out.normals.push_back(pts.normals[i]);
    for (const auto& [name, v] : pts.vertex_scalars) out.vertex_scalars[name].push_back(v[i]);
  }
  pts = std::move(out);
  return dropped;
}

SurfaceMeshResult mesh_surface_from_particles(const Mesh& pts, const ScalarField& f, double iso,
                                              const SurfaceMeshParams& p, const std::string& what) {
  if (p.improve > 0 && !p.repair) throw UsageError("--improve needs a manifold surface: drop --no-repair");
  require_particles(pts, what);
  SurfaceMeshResult res;
  res.tets = delaunay_of(what, pts, true);
  {
    ScopedStage s("label");
    // Circumcentres of hull tetrahedra can lie far outside the volume, where
    // a reconstructed field only replicates its border: outside the domain
    // is outside the material.
    const Box dom = f.domain();
    res.below = p.inside == InsideSide::automatic ? material_below_iso(f, iso) : p.inside == InsideSide::below;
    const bool below = res.below;
    res.label_stats = label_tets(res.tets, [&](const Vec3& x) {
      if (!dom.contains(x)) return 0;
      const double v = f.value(x);
      return (below ? v < iso : v > iso) ? 1 : 0;
    });
  }
  if (p.repair) {
    ScopedStage s("manifold");
    res.relabelled = make_manifold(res.tets, 1, 0);
  }
  Mesh& surf = res.surface;
  surf = material_surface(res.tets, 1, 0);
  if (surf.faces.empty())
    throw InputError(what + ": no tetrahedron is inside the surface F < " + std::to_string(iso) +
                     "; expected particles sampling the isosurface");
  if (pts.has_normals()) {
    surf.normals.resize(surf.vertices.size());
    const auto& idx = surf.vertex_scalars.at("index");
    for (std::size_t i = 0; i < surf.vertices.size(); ++i) surf.normals[i] = pts.normals[std::size_t(idx[i])];
  }
  const MeshTopology& t = res.topology = mesh_topology(surf);
  res.buried = pts.vertices.size() - t.vertices;
  if (!t.closed_manifold())
    res.warnings.push_back("the surface is not a closed manifold: " + std::to_string(t.boundary_edges) +
                           " boundary edges, " + std::to_string(t.nonmanifold_edges) + " non-manifold edges, " +
                           std::to_string(t.nonmanifold_vertices) + " non-manifold vertices");
  if (res.buried > 0)
    res.warnings.push_back(std::to_string(res.buried) +
                           " particles are not on the surface (off the isosurface, or too close)");
  if (p.improve > 0 && !t.closed_manifold()) {
    // Flips and the crossing check need a closed manifold: keep the plain
    // surface (meshstats reports what is wrong with it) rather than fail.
    res.warnings.push_back(
        "--improve skipped: the Delaunay surface is not a closed manifold (see above); the plain surface is written");
  } else if (p.improve > 0) {
    ScopedStage s("improve");
    SurfaceImproveParams ip;
    ip.rounds = p.improve;
    ip.input_embedded = true;  // faces of the Delaunay tetrahedra: none cross
    res.improve = improve_surface(surf, f, iso, ip);
  }
  return res;
}

MaterialStageResult mesh_materials_from_particles(Mesh pts, const MaterialSet& ms, const MaterialStageParams& p,
                                                  const std::string& what) {
  require_particles(pts, what);
  if (p.improve > 0 && !p.repair) throw UsageError("--improve needs manifold surfaces: drop --no-repair");
  MaterialStageResult res;
  MaterialMeshParams mp;
  mp.repair = p.repair;
  mp.outside_label = p.outside_label ? *p.outside_label : auto_outside_label(ms);
  res.outside_label = mp.outside_label;
  {
    Box b;
    for (const auto& v : pts.vertices) b.extend(v);
    res.duplicates = drop_duplicate_points(pts, 1e-7 * std::max(norm(b.size()), 1e-300));
    if (res.duplicates > 0)
      res.warnings.push_back(std::to_string(res.duplicates) +
                             " duplicate particle(s) dropped (within 1e-7 of the bounding box diagonal)");
  }
  res.particles = pts.vertices.size();
  res.tets = delaunay_of(what, pts, false);
  MaterialMeshes& mm = res.meshes;
  {
    ScopedStage s("label");
    mm = mesh_materials(res.tets, ms, mp);
  }
  if (mm.interfaces.faces.empty())
    throw InputError(what + ": every tetrahedron has the same material (" +
                     std::to_string(res.tets.labels.empty() ? mp.outside_label : res.tets.labels[0]) +
                     "); expected particles sampling the interfaces between materials");
  copy_point_scalars(pts, mm.interfaces);
  const MeshTopology& it = res.interface_topology = mesh_topology(mm.interfaces);
  if (it.boundary_edges > 0)
    res.warnings.push_back("the interface mesh has " + std::to_string(it.boundary_edges) + " boundary edges");
  for (int l : mm.nonmanifold_materials)
    res.warnings.push_back("the surface of material " + std::to_string(l) +
                           " is not a closed manifold after the repair");
  res.buried = pts.vertices.size() - it.vertices;
  if (res.buried > 0)
    res.warnings.push_back(std::to_string(res.buried) +
                           " particles are not on any interface (off the interfaces, or too close)");
  if (p.improve > 0) {
    ScopedStage s("improve");
    SurfaceImproveParams ip;
    ip.rounds = p.improve;
    ip.input_embedded = true;  // faces of the (relabelled) Delaunay tetrahedra: none cross
    res.improve = improve_interfaces(mm.interfaces, ms, ip);
  }
  // Each material's surface on its own, side by side.
  std::vector<std::pair<const int, Mesh>*> surfaces;
  for (auto& lm : mm.surfaces) surfaces.push_back(&lm);
  const bool rebuild = p.improve > 0;
  pm::parallel_tasks(surfaces.size(), [&](std::size_t i) {
    auto& [l, m] = *surfaces[i];
    if (rebuild) m = material_from_interfaces(mm.interfaces, l);
    copy_point_scalars(pts, m);
  });
  return res;
}

SurfacePipelineResult mesh_surface_pipeline(const Volume& in, const SurfacePipelineParams& p,
                                            const std::string& what) {
  SurfacePipelineResult res;
  require_finite(in, what);
  // What the input is: a mask (LABELS given, or exactly two integer values)
  // or grey levels.
  bool two_values = false;
  if (is_integer(in.type())) {
    try {
      two_values = label_counts(in, 2).size() == 2;
    } catch (const InputError&) {
    }
  }
  const bool mask = !p.labels.empty() || two_values;
  res.kind = mask ? "mask" : "grey";
  check_surface_input(in, mask, p.iso, what);
  if (p.decimate < 1) throw UsageError("--decimate " + std::to_string(p.decimate) + "; expected >= 1");
  if (!(p.eps > 0)) throw UsageError("--eps " + num(p.eps) + "; expected > 0");
  if (!(p.delta > 0)) throw UsageError("--delta " + num(p.delta) + "; expected > 0 (e.g. 0.3)");
  if (p.spacing < 0) throw UsageError("--spacing " + num(p.spacing) + "; expected > 0 world units (0 = sizing field)");
  const bool use_mask = mask || p.morph || p.tighten;
  const double hs = min_spacing(in);
  const std::size_t n_stages = (use_mask ? 3 : 1) + (p.spacing > 0 ? 0 : 3) + 3;
  Stages stages("ch5", n_stages, p.progress, res.seconds);

  Volume sdf;  // for the sizing field
  if (use_mask) {
    Volume m;
    stages.run("mask", [&] {
      if (!p.labels.empty()) m = label_mask(in, p.labels, what);
      else if (mask) m = in.converted(VoxelType::u8);
      else m = threshold(in, *p.iso, what);
    });
    stages.run("morphology", [&] {
      LabelMorphParams mp;
      const Stencil st = parse_stencil(p.stencil);
      mp.steps = {MorphStep{MorphOp::close, st, 1}, MorphStep{MorphOp::open, st, 1}};
      mp.min_component = p.min_component;
      try {
        require_labels(m, what);
        LabelMorphResult r = morph_labels(m, mp);
        kept_label_warnings(r, res.warnings);
        m = std::move(r.labels);
      } catch (const InputError& e) {
        throw InputError(what + ": " + e.what());
      }
    });
    stages.run("tighten", [&] {
      // tighten --radius R --upsample K, auto from morph.nrrd's header and size.
      const TightenDefaults td = tighten_defaults(m, p.radius, p.upsample);
      TightenParams tp;
      tp.radius = td.radius;
      tp.upsample = td.upsample;
      TightenResult r;
      try {
        r = tighten(m, tp);
      } catch (const InputError& e) {
        throw InputError(what + ": " + e.what());
      }
      if (r.pad > 0)
        res.warnings.push_back("the mask comes within R + 3 voxels of the border: padded by " +
                               std::to_string(r.pad) + " voxels on every side (output origin moved)");
      if (!r.converged)
        res.warnings.push_back("tighten: not converged after " + std::to_string(r.iterations) + " steps");
      sdf = std::move(r.distance);
    });
    res.field = sdf;
    res.field_iso = 0;
  } else {
    stages.run("distance", [&] { sdf = grey_distance(in, *p.iso, what); });
    res.field = in;
    res.field_iso = *p.iso;
  }

  std::unique_ptr<SizingField> sizing;
  if (!(p.spacing > 0)) {
    std::vector<Vec3> ma;
    stages.run("medialaxis", [&] { ma = medial_points(sdf, what); });
    Volume h0;
    stages.run("sizingfield", [&] {
      SizingFieldParams sp;
      sp.eps = p.eps;
      sp.hmin = p.hmin > 0 ? p.hmin : hs / 2;
      require_distance_volume(sdf, what);
      h0 = sizing_field({SizingSurface{sdf, ma}}, sp).h;
    });
    stages.run("gradlimit", [&] {
      GradLimitParams gp;
      gp.delta = p.delta;
      sizing = std::make_unique<SizingField>(gradient_limit(h0, gp).h, "h");
    });
  }

  std::vector<Vec3> seeds;
  stages.run("mcinit", [&] {
    McInitParams mp;
    mp.iso = res.field_iso;
    mp.decimate = p.decimate;
    try {
      seeds = as_stored(mc_seeds(res.field, mp).seeds.vertices);
    } catch (const InputError& e) {
      throw InputError(what + ": " + e.what());
    }
  });
  // particles and tetlabel reconstruct the field with the B-spline (their default).
  const VolumeField field(res.field, {}, what);
  stages.run("particles", [&] {
    ParticleParams pp;
    pp.iso = res.field_iso;
    pp.spacing = p.spacing;
    pp.tolerance = p.tolerance;
    pp.coarse_to_fine = true;
    pp.init_lattice = true;
    pp.seed = p.seed;
    pp.progress = p.progress;
    const ParticleResult r = distribute_particles(field, seeds, sizing.get(), pp);
    if (!r.converged)
      res.warnings.push_back("particles: not converged after " + std::to_string(r.iterations) + " iterations");
    Mesh& m = res.particles;
    m.vertices = r.positions;
    m.normals = r.normals;
    m.vertex_scalars["energy"] = r.energy;
    m.vertex_scalars["spacing"] = r.spacing;
    m.vertex_scalars["curvature"] = r.curvature;
    m = as_stored(std::move(m));
  });
  stages.run("tetlabel", [&] {
    SurfaceMeshParams sp;
    sp.improve = p.improve;
    SurfaceMeshResult r = mesh_surface_from_particles(res.particles, field, res.field_iso, sp, "particles");
    res.surface = std::move(r.surface);
    res.tets = std::move(r.tets);
    for (auto& w : r.warnings) res.warnings.push_back("tetlabel: " + w);
  });
  return res;
}

MaterialsPipelineResult mesh_materials_pipeline(const Volume& in, const MaterialsPipelineParams& p,
                                                const std::string& what) {
  MaterialsPipelineResult res;
  if (p.decimate < 1) throw UsageError("--decimate " + std::to_string(p.decimate) + "; expected >= 1");
  if (p.downsample < 1) throw UsageError("--downsample " + std::to_string(p.downsample) + "; expected >= 1");
  if (!(p.eps > 0)) throw UsageError("--eps " + num(p.eps) + "; expected > 0");
  if (!(p.delta > 0)) throw UsageError("--delta " + num(p.delta) + "; expected > 0 (e.g. 0.3)");
  if (p.spacing < 0) throw UsageError("--spacing " + num(p.spacing) + "; expected > 0 world units (0 = sizing field)");
  if (p.ma_side != "inside" && p.ma_side != "outside" && p.ma_side != "both")
    throw UsageError("MA_SIDE " + quote(p.ma_side) + "; expected inside, outside or both");
  const bool morph = !(p.morph_ops == "none" && p.downsample == 1);
  Stages stages("ch6", (morph ? 6 : 5) + (p.spacing > 0 ? 0 : 2), p.progress, res.seconds);

  // volconv --type smallest [--merge] [--min-voxels] [--pad --pad-value]
  Volume lv;
  stages.run("labels", [&] {
    lv = in;
    require_finite(lv, what);
    if (!p.merge.empty()) {
      const auto rules = parse_merge_spec(p.merge);
      require_labels(lv, what);
      lv = merge_labels(lv, rules);
    }
    if (p.min_voxels > 0) {
      require_labels(lv, what);
      try {
        lv = drop_small_labels(lv, p.min_voxels);
      } catch (const InputError& e) {
        throw InputError(what + ": " + e.what());
      }
    }
    if (p.pad < -1) throw UsageError("--pad " + std::to_string(p.pad) + "; expected >= 0 voxels or -1 (auto)");
    std::size_t pad = p.pad >= 0 ? std::size_t(p.pad) : 0;
    const std::string pad_value = !p.pad_value.empty() ? p.pad_value : p.pad < 0 ? "auto" : "new";
    if (p.pad < 0) {
      require_labels(lv, what);
      if (border_padding(lv).pad) pad = kAutoPadVoxels * std::size_t(p.downsample);
    }
    if (pad > 0) lv = padded(lv, pad, pad_value_of(lv, pad_value, what));
    lv = lv.converted(smallest_integer_type(lv));
  });
  // morph --labels all --ops MORPH_OPS [--downsample] --vote
  if (morph) {
    stages.run("morphology", [&] {
      LabelMorphParams mp;
      try {
        require_labels(lv, what);
        mp.all_labels = true;
        if (p.morph_ops != "none") mp.steps = parse_morph_steps(p.morph_ops);
        mp.downsample = p.downsample;
        mp.vote = true;
        LabelMorphResult r = morph_labels(lv, mp);
        kept_label_warnings(r, res.warnings);
        lv = std::move(r.labels);
      } catch (const InputError& e) {
        throw InputError(what + ": " + e.what());
      }
    });
  }
  res.labels = lv;
  // tighten --per-label: one signed distance per label, one grid.
  std::vector<int> labels;
  std::vector<Volume> sdfs;
  double radius = 0;  // HMIN's default: half the radius tighten used (the radius when upsampled)
  stages.run("tighten", [&] {
    // tighten --per-label --radius R --upsample K, auto from morph.nrrd's header and size.
    const TightenDefaults td = tighten_defaults(lv, p.radius, p.upsample);
    radius = td.upsample > 1 ? td.radius : td.radius / 2;  // HMIN auto, as Makefile.ch6
    TightenParams tp;
    tp.radius = td.radius;
    tp.upsample = td.upsample;
    // TIGHTEN_BAND auto with MA_SIDE=inside, 0 (exact) otherwise.
    if (p.ma_side == "inside") tp.outside_band = tighten_outside_band_auto(lv.geometry(), td.upsample);
    try {
      tighten_labels(lv, tp, [&](int label, TightenResult&& r) {
        if (r.radius < r.requested_radius)
          res.warnings.push_back("tighten: label " + std::to_string(label) + ": " + tighten_radius_note(r));
        if (!r.converged)
          res.warnings.push_back("tighten: label " + std::to_string(label) + ": not converged after " +
                                 std::to_string(r.iterations) + " steps");
        labels.push_back(label);
        sdfs.push_back(std::move(r.distance));
      });
    } catch (const InputError& e) {
      throw InputError(what + ": " + e.what());
    }
  });
  // The material set "L=sdf_L.nrrd,...", Catmull-Rom (the tools' default).
  MaterialSet ms;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    ms.labels.push_back(labels[i]);
    ms.fields.push_back(std::make_shared<VolumeField>(
        sdfs[i], VolumeFieldParams{KernelType::catmull_rom, KernelType::catmull_rom},
        "sdf_" + std::to_string(labels[i])));
  }
  if (ms.size() < 2)
    throw InputError(what + " has " + std::to_string(ms.size()) + " material(s); expected at least 2");

  std::unique_ptr<SizingField> sizing;
  if (!(p.spacing > 0)) {
    std::vector<std::vector<Vec3>> mas(sdfs.size());
    stages.run("medialaxis", [&] {
      for (std::size_t i = 0; i < sdfs.size(); ++i)
        mas[i] = medial_points(sdfs[i], what + " label " + std::to_string(labels[i]), true, p.ma_side);
    });
    stages.run("sizingfield", [&] {
      SizingFieldParams sp;
      sp.eps = p.eps;
      sp.hmin = p.hmin >= 0 ? p.hmin : radius;
      // A material without medial-axis points (the corner voxel of a tiny
      // volume) adds no feature size; when none has any, h = HMIN everywhere.
      std::vector<SizingSurface> surfaces;
      for (std::size_t i = 0; i < sdfs.size(); ++i)
        if (!mas[i].empty()) surfaces.push_back({sdfs[i], mas[i]});
      Volume h0;
      if (surfaces.empty()) {
        res.warnings.push_back("no material has a medial axis (a volume of a few voxels): h = HMIN = " +
                               format_number(sp.hmin) + " everywhere");
        h0 = Volume(VoxelType::f32, sdfs[0].dims(), sdfs[0].geometry());
        for (std::size_t i = 0; i < h0.count(); ++i) h0.set(i, sp.hmin);
      } else {
        h0 = sizing_field(surfaces, sp).h;
      }
      GradLimitParams gp;
      gp.delta = p.delta;
      sizing = std::make_unique<SizingField>(gradient_limit(h0, gp).h, "h");
    });
  }
  // volconv MATERIALS --argmax, then mcinit --junctions.
  std::vector<JunctionSeed> seeds;
  stages.run("mcinit", [&] {
    const Volume am = argmax_labels(ms, sdfs[0]);
    JunctionParams jp;
    jp.decimate = p.decimate;
    Mesh sm;
    try {
      sm = as_stored(junction_seeds(am, jp).seeds);
    } catch (const InputError& e) {
      throw InputError(what + ": " + e.what());
    }
    seeds = junction_seeds_from_mesh(sm, "junction seeds");
    if (seeds.empty())
      throw InputError(what + ": no junction seeds; expected points on the material boundaries");
  });
  stages.run("multiparticles", [&] {
    MultiParticleParams mp;
    mp.spacing = p.spacing;
    mp.seed = p.seed;
    mp.progress = p.progress;
    const MultiParticleResult r = distribute_multi_particles(ms, seeds, sizing.get(), mp);
    for (int l = 1; l < 3; ++l)
      if (r.levels[std::size_t(l)].particles && !r.levels[std::size_t(l)].converged)
        res.warnings.push_back(std::string("multiparticles: ") + (l == 1 ? "curves" : "surfaces") +
                               " not converged");
    res.particles = as_stored(multi_particles_mesh(r));
  });
  stages.run("tetlabel", [&] {
    MaterialStageParams sp;
    sp.improve = p.improve;
    res.meshes = mesh_materials_from_particles(res.particles, ms, sp, "particles");
    for (auto& w : res.meshes.warnings) res.warnings.push_back("tetlabel: " + w);
  });
  return res;
}

}  // namespace pm

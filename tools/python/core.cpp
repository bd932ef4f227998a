// particlemesh._core: the Python front end's compiled part (pybind11). Numpy
// arrays in, the libcore calls the tools make, numpy arrays out; the pure
// Python package (particlemesh/__init__.py) adds the result types, tqdm and
// meshio. Arrays are indexed [i, j, k] (axis 0 = the volume's x axis, as
// nibabel does), C or Fortran order; world units from origin, spacing and
// directions, as in the volume files.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/volume.h"
#include "pm/cli/energy_option.h"
#include "pm/field/sizing.h"
#include "pm/field/volume_field.h"
#include "pm/io/volume_io.h"
#include "pm/mesh/pipeline.h"
#include "pm/sample/particles.h"

namespace py = pybind11;

namespace {

// --- arrays <-> volumes ---------------------------------------------------------

std::optional<pm::VoxelType> voxel_type_of(const py::dtype& dt) {
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'b') return pm::VoxelType::u8;
  if (kind == 'u') {
    if (size == 1) return pm::VoxelType::u8;
    if (size == 2) return pm::VoxelType::u16;
    if (size == 4) return pm::VoxelType::u32;
    if (size == 8) return pm::VoxelType::u64;
  }
  if (kind == 'i') {
    if (size == 1) return pm::VoxelType::i8;
    if (size == 2) return pm::VoxelType::i16;
    if (size == 4) return pm::VoxelType::i32;
    if (size == 8) return pm::VoxelType::i64;
  }
  if (kind == 'f') {
    if (size == 4) return pm::VoxelType::f32;
    if (size == 8) return pm::VoxelType::f64;
  }
  return std::nullopt;
}

py::dtype dtype_of(pm::VoxelType t) {
  switch (t) {
    case pm::VoxelType::u8: return py::dtype::of<std::uint8_t>();
    case pm::VoxelType::i8: return py::dtype::of<std::int8_t>();
    case pm::VoxelType::u16: return py::dtype::of<std::uint16_t>();
    case pm::VoxelType::i16: return py::dtype::of<std::int16_t>();
    case pm::VoxelType::u32: return py::dtype::of<std::uint32_t>();
    case pm::VoxelType::i32: return py::dtype::of<std::int32_t>();
    case pm::VoxelType::u64: return py::dtype::of<std::uint64_t>();
    case pm::VoxelType::i64: return py::dtype::of<std::int64_t>();
    case pm::VoxelType::f32: return py::dtype::of<float>();
    case pm::VoxelType::f64: return py::dtype::of<double>();
  }
  return py::dtype::of<double>();
}

std::string shape_text(const py::array& a) {
  std::ostringstream s;
  s << "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s << (d ? ", " : "") << a.shape(d) << (a.ndim() == 1 ? "," : "");
  s << ")";
  return s.str();
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

enum class Values { any, labels };

// A numpy array (3-D, C or Fortran contiguous, a supported dtype) as a
// pm::Volume with the given geometry. \throw py::value_error naming `arg`.
pm::Volume to_volume(const py::array& a, const std::string& arg, Values values, const pm::Geometry& g) {
  if (a.ndim() != 3)
    throw py::value_error(arg + ": expected a 3-D array indexed [i, j, k], got " + std::to_string(a.ndim()) +
                          "-D with shape " + shape_text(a));
  const auto vt = voxel_type_of(a.dtype());
  const std::string dt = py::str(a.dtype());
  if (!vt)
    throw py::value_error(arg + ": unsupported dtype " + dt +
                          "; expected bool, (u)int8/16/32/64, float32 or float64");
  if (values == Values::labels && (*vt == pm::VoxelType::f32 || *vt == pm::VoxelType::f64))
    throw py::value_error(arg + ": dtype " + dt + "; expected an integer array of labels (e.g. numpy.int32)");
  const bool c = (a.flags() & py::array::c_style) != 0, f = (a.flags() & py::array::f_style) != 0;
  if (!c && !f)
    throw py::value_error(arg + ": the array is not contiguous (a strided view, e.g. a[::2]); expected a C or "
                          "Fortran contiguous array: pass numpy.ascontiguousarray(" + arg + ")");
  for (int d = 0; d < 3; ++d)
    if (a.shape(d) < 1) throw py::value_error(arg + ": shape " + shape_text(a) + " has an empty axis; expected >= 1");
  const pm::Dims dims{std::size_t(a.shape(0)), std::size_t(a.shape(1)), std::size_t(a.shape(2))};
  pm::Volume v(*vt, dims, g);
  const std::size_t es = pm::voxel_size(*vt);
  const auto* src = static_cast<const unsigned char*>(a.data());
  auto* dst = static_cast<unsigned char*>(v.raw());
  if (f || dims.count() == 1) {
    std::memcpy(dst, src, v.byte_size());
  } else {  // C order: k fastest in memory, i fastest in the volume
    for (std::size_t i = 0; i < dims.nx; ++i)
      for (std::size_t j = 0; j < dims.ny; ++j) {
        const unsigned char* row = src + ((i * dims.ny + j) * dims.nz) * es;
        for (std::size_t k = 0; k < dims.nz; ++k) std::memcpy(dst + v.index(i, j, k) * es, row + k * es, es);
      }
  }
  if (*vt == pm::VoxelType::u8 && a.dtype().kind() == 'b')
    for (std::size_t i = 0; i < v.count(); ++i) dst[i] = dst[i] ? 1 : 0;
  return v;
}

// A volume as a Fortran-ordered numpy array indexed [i, j, k].
py::array to_array(const pm::Volume& v) {
  const std::size_t es = pm::voxel_size(v.type());
  const pm::Dims& d = v.dims();
  std::vector<py::ssize_t> shape{py::ssize_t(d.nx), py::ssize_t(d.ny), py::ssize_t(d.nz)};
  std::vector<py::ssize_t> strides{py::ssize_t(es), py::ssize_t(es * d.nx), py::ssize_t(es * d.nx * d.ny)};
  py::array a(dtype_of(v.type()), shape, strides);
  std::memcpy(a.mutable_data(), v.raw(), v.byte_size());
  return a;
}

std::vector<double> floats(const py::object& o, const std::string& arg) {
  try {
    return o.cast<std::vector<double>>();
  } catch (const py::cast_error&) {
    throw py::value_error(arg + ": expected a sequence of numbers, got " + std::string(py::str(py::type::of(o))));
  }
}

// origin (3 finite numbers), voxel_spacing (one or 3 numbers > 0) and
// directions (3x3, column a = unit world direction of axis a).
pm::Geometry to_geometry(const py::object& origin, const py::object& spacing, const py::object& directions) {
  pm::Vec3 o(0, 0, 0);
  if (!origin.is_none()) {
    const auto v = floats(origin, "origin");
    if (v.size() != 3 || !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); }))
      throw py::value_error("origin: expected 3 finite numbers (world units)");
    o = pm::Vec3(v[0], v[1], v[2]);
  }
  std::vector<double> s{1, 1, 1};
  if (!spacing.is_none()) {
    if (py::isinstance<py::float_>(spacing) || py::isinstance<py::int_>(spacing)) {
      s.assign(3, spacing.cast<double>());
    } else {
      s = floats(spacing, "voxel_spacing");
    }
    if (s.size() != 3)
      throw py::value_error("voxel_spacing: expected one or 3 numbers, got " + std::to_string(s.size()));
    for (double x : s)
      if (!(x > 0) || !std::isfinite(x))
        throw py::value_error("voxel_spacing: " + num(x) + " is not positive; expected spacings > 0 (world units)");
  }
  pm::Mat3 dm = pm::Mat3::identity();
  if (!directions.is_none()) {
    std::vector<std::vector<double>> m;
    try {
      m = directions.cast<std::vector<std::vector<double>>>();
    } catch (const py::cast_error&) {
      throw py::value_error("directions: expected a 3x3 matrix whose column a is the unit direction of axis a");
    }
    if (m.size() != 3 || m[0].size() != 3 || m[1].size() != 3 || m[2].size() != 3)
      throw py::value_error("directions: expected a 3x3 matrix whose column a is the unit direction of axis a");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) dm.m[std::size_t(r)][std::size_t(c)] = m[std::size_t(r)][std::size_t(c)];
    for (int c = 0; c < 3; ++c) {
      const double n = pm::norm(dm.column(c));
      if (!(std::abs(n - 1) < 1e-4))
        throw py::value_error("directions: column " + std::to_string(c) + " has length " + num(n) +
                              "; expected unit directions (the spacing goes in voxel_spacing)");
    }
  }
  pm::Geometry g;
  g.origin = o;
  const pm::Mat3 sc = pm::Mat3::diag(s[0], s[1], s[2]);
  g.directions = dm * sc;
  return g;
}

py::array_t<double> points_array(const std::vector<pm::Vec3>& p) {
  py::array_t<double> a({py::ssize_t(p.size()), py::ssize_t(3)});
  auto m = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int c = 0; c < 3; ++c) m(py::ssize_t(i), c) = p[i][c];
  return a;
}

template <class T, std::size_t N>
py::array_t<std::int64_t> index_array(const std::vector<std::array<T, N>>& f) {
  py::array_t<std::int64_t> a({py::ssize_t(f.size()), py::ssize_t(N)});
  auto m = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < f.size(); ++i)
    for (std::size_t c = 0; c < N; ++c) m(py::ssize_t(i), py::ssize_t(c)) = f[i][c];
  return a;
}

py::array_t<double> scalars(const std::vector<double>& v) { return py::array_t<double>(py::ssize_t(v.size()), v.data()); }

py::dict mesh_dict(const pm::Mesh& m) {
  py::dict d;
  d["points"] = points_array(m.vertices);
  d["triangles"] = index_array(m.faces);
  if (m.has_normals()) d["normals"] = points_array(m.normals);
  py::dict ps;
  for (const auto& [name, v] : m.vertex_scalars) ps[py::str(name)] = scalars(v);
  d["point_data"] = ps;
  py::dict fs;
  for (const auto& [name, v] : m.face_ints) fs[py::str(name)] = py::array_t<std::int64_t>(
      py::ssize_t(v.size()), std::vector<std::int64_t>(v.begin(), v.end()).data());
  d["cell_data"] = fs;
  return d;
}

// Tetrahedra whose label differs from `outside` (what write_medit writes).
py::dict tets_dict(const pm::TetMesh& tm, int outside) {
  std::vector<std::array<int, 4>> t;
  std::vector<std::int64_t> l;
  for (std::size_t i = 0; i < tm.tets.size(); ++i)
    if (tm.labels[i] != outside) {
      t.push_back(tm.tets[i]);
      l.push_back(tm.labels[i]);
    }
  py::dict d;
  d["points"] = points_array(tm.points);
  d["tets"] = index_array(t);
  d["labels"] = py::array_t<std::int64_t>(py::ssize_t(l.size()), l.data());
  return d;
}

// --- a run: one at a time, GIL released, progress and Ctrl-C -------------------

std::mutex g_run_mutex;

// Installs the hooks for one libcore call made with the GIL released: the
// progress callback (with the GIL) and Python's signal check, so Ctrl-C
// (KeyboardInterrupt) or an exception raised by the callback stops the run
// through pm::Cancelled and is re-raised here afterwards.
class Run {
 public:
  Run(py::object progress, int threads)
      : progress_(std::move(progress)),
        threads_(threads > 0 ? std::size_t(threads) : std::size_t(std::max(1u, std::thread::hardware_concurrency()))) {
    if (threads < 0) throw py::value_error("threads: " + std::to_string(threads) + "; expected >= 0 (0 = all cores)");
  }

  template <class F>
  auto operator()(F&& f) -> decltype(f()) {
    std::optional<decltype(f())> result;
    {
      py::gil_scoped_release nogil;
      std::lock_guard<std::mutex> lock(g_run_mutex);
      tbb::global_control control(tbb::global_control::max_allowed_parallelism, threads_);
      pm::set_cancel_hook([this] { return cancel(); });
      pm::set_warning_hook([this](const std::string& msg) { warnings_.push_back(msg); });
      if (!progress_.is_none())
        pm::set_progress_hook([this](const std::string& label, std::size_t done, std::size_t total,
                                     const std::string& detail) { report(label, done, total, detail); });
      struct Reset {
        ~Reset() {
          pm::set_cancel_hook({});
          pm::set_progress_hook({});
          pm::set_warning_hook({});
        }
      } reset;
      try {
        result.emplace(f());
      } catch (const pm::Cancelled&) {
        // re-raised below with the GIL
      }
    }
    if (error_) {
      error_->restore();
      throw py::error_already_set();
    }
    if (!result) {
      PyErr_SetString(PyExc_KeyboardInterrupt, "cancelled");
      throw py::error_already_set();
    }
    return std::move(*result);
  }

  /// What libcore passed to pm::warn during the run (called under its log lock).
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  bool cancel() {
    py::gil_scoped_acquire gil;
    if (error_) return true;
    if (PyErr_CheckSignals() != 0) {
      error_.emplace();  // fetches the pending exception (KeyboardInterrupt)
      return true;
    }
    return false;
  }

  void report(const std::string& label, std::size_t done, std::size_t total, const std::string& detail) {
    py::gil_scoped_acquire gil;
    if (error_) throw pm::Cancelled("cancelled");
    try {
      progress_(label, done, total, detail);
    } catch (py::error_already_set& e) {
      error_.emplace(std::move(e));
      throw pm::Cancelled("cancelled");
    }
  }

  py::object progress_;
  std::size_t threads_;
  std::optional<py::error_already_set> error_;
  std::vector<std::string> warnings_;
};

// The stages' warnings, then libcore's pm::warn lines of the run.
py::list warnings_list(const std::vector<std::string>& w, const Run& run) {
  py::list l;
  for (const auto& s : w) l.append(s);
  for (const auto& s : run.warnings()) l.append(s);
  return l;
}

py::dict seconds_dict(const std::map<std::string, double>& s) {
  py::dict d;
  for (const auto& [k, v] : s) d[py::str(k)] = v;
  return d;
}

// --- the functions --------------------------------------------------------------

py::dict read_volume(const std::string& path) {
  Run run(py::none(), 0);
  const pm::Volume v = run([&] { return pm::read_volume(path); });
  const pm::Geometry& g = v.geometry();
  py::dict d;
  d["array"] = to_array(v);
  d["origin"] = std::vector<double>{g.origin.x, g.origin.y, g.origin.z};
  d["spacing"] = std::vector<double>{g.spacing(0), g.spacing(1), g.spacing(2)};
  std::vector<std::vector<double>> dirs(3, std::vector<double>(3));
  for (int c = 0; c < 3; ++c) {
    const pm::Vec3 col = g.directions.column(c) / g.spacing(c);
    for (int r = 0; r < 3; ++r) dirs[std::size_t(r)][std::size_t(c)] = col[r];
  }
  d["directions"] = dirs;
  // libcore's world frame (pm/base/volume.h), as volconv --info reports it.
  const pm::FrameSource& f = v.frame_source();
  d["frame"] = f.anatomical ? "LPS" : "none";
  d["source_format"] = f.format;
  d["source_space"] = f.space;
  d["frame_note"] = f.note;
  d["warnings"] = warnings_list({}, run);
  return d;
}

pm::VolumeFieldParams kernel_params(const std::string& k) {
  if (k == "bspline") return {};
  if (k == "catmull-rom") return {pm::KernelType::catmull_rom, pm::KernelType::catmull_rom};
  if (k == "mix") return pm::VolumeFieldParams::chapter5_mix();
  throw py::value_error("kernel: \"" + k + "\" is unknown; expected bspline, catmull-rom or mix");
}

py::dict sample(const py::array& array, const py::object& origin, const py::object& voxel_spacing,
                const py::object& directions, double iso, std::optional<double> spacing, double density,
                double alpha_cap, std::optional<py::array> sizing, const py::object& sizing_origin,
                const py::object& sizing_spacing, const py::object& sizing_directions, std::optional<py::array> init,
                std::size_t init_count, std::optional<bool> lattice_init, std::size_t count, const std::string& kernel,
                const std::string& energy, double tolerance, double population_tolerance, bool population,
                int max_iters, std::optional<bool> coarse_to_fine, double coarse_start, double thin_seeds,
                double settle, std::uint64_t seed, int threads, py::object progress) {
  // The particles tool's checks, named by keyword.
  if (!sizing && !spacing) throw py::value_error("spacing: required (world units) unless sizing is given");
  if (sizing && spacing) throw py::value_error("spacing: give spacing or sizing, not both");
  if (sizing && density != 0) throw py::value_error("density: does not apply with sizing");
  if (!(thin_seeds >= 0 && thin_seeds <= 1.99))
    throw py::value_error("thin_seeds: " + num(thin_seeds) + "; expected 0 to 1.99 (a fraction of the spacing)");
  if (!(settle >= 0 && settle <= 0.99))
    throw py::value_error("settle: " + num(settle) + "; expected 0 to 0.99 (a fraction of the spacing)");
  if (energy != "cotangent" && energy != "radial")
    throw py::value_error("energy: \"" + energy + "\" is unknown; expected cotangent or radial");
  const pm::VolumeFieldParams kp = kernel_params(kernel);
  const pm::Volume v = to_volume(array, "array", Values::any, to_geometry(origin, voxel_spacing, directions));
  pm::require_finite(v, "array");
  const pm::ValueRange r = pm::value_range(v);
  if (!(iso > r.lo && iso < r.hi))
    throw py::value_error("iso: " + num(iso) + " is outside the value range [" + num(r.lo) + ", " + num(r.hi) +
                          "] of the array; expected min < iso < max");
  std::optional<pm::Volume> hv;
  if (sizing)
    hv = to_volume(*sizing, "sizing", Values::any, to_geometry(sizing_origin, sizing_spacing, sizing_directions));
  std::vector<pm::Vec3> seeds;
  if (init) {
    const py::array_t<double, py::array::c_style | py::array::forcecast> s(*init);
    if (s.ndim() != 2 || s.shape(1) != 3)
      throw py::value_error("init: expected an N x 3 array of seed points (world units), got shape " + shape_text(s));
    if (s.shape(0) == 0) throw py::value_error("init: no seed points; expected an N x 3 array with N >= 1");
    auto m = s.unchecked<2>();
    for (py::ssize_t i = 0; i < s.shape(0); ++i) seeds.emplace_back(m(i, 0), m(i, 1), m(i, 2));
  }
  pm::ParticleParams p;
  p.iso = iso;
  p.spacing = spacing.value_or(0);
  p.density = density;
  p.alpha_cap = alpha_cap;
  p.energy = pm::energy_named(energy);  // checked above with a Python-style message
  p.tolerance = tolerance;
  p.population_tolerance = population_tolerance;
  p.population_control = population;
  p.max_iters = max_iters;
  p.count = count;
  p.init_count = init_count;
  p.init_lattice = lattice_init.value_or(true);  // the tool's default for volumes
  p.coarse_to_fine = coarse_to_fine.value_or(true);
  p.coarse_start = coarse_start;
  p.seed_thinning = thin_seeds;
  p.settled_move = settle;
  p.seed = seed;
  p.progress = true;
  Run run(std::move(progress), threads);
  const pm::ParticleResult res = run([&] {
    const pm::VolumeField field(v, kp, "array");
    std::unique_ptr<pm::SizingField> h;
    if (hv) h = std::make_unique<pm::SizingField>(*hv, "sizing");
    return pm::distribute_particles(field, seeds, h.get(), p);
  });
  py::dict d;
  d["points"] = points_array(res.positions);
  d["normals"] = points_array(res.normals);
  d["energy"] = scalars(res.energy);
  d["spacing"] = scalars(res.spacing);
  d["curvature"] = scalars(res.curvature);
  d["converged"] = res.converged;
  d["iterations"] = res.iterations;
  d["warnings"] = warnings_list({}, run);
  return d;
}

py::dict mesh_surface(const py::array& array, const py::object& origin, const py::object& voxel_spacing,
                      const py::object& directions, std::optional<double> iso, std::vector<std::int64_t> labels,
                      const std::string& stencil, std::size_t min_component, std::optional<double> radius,
                      std::optional<int> upsample, double eps, double delta, std::optional<double> spacing,
                      std::optional<double> hmin, bool morph, bool tighten, int decimate, double tolerance,
                      int improve, bool tetrahedra, std::uint64_t seed, int threads, py::object progress) {
  if (spacing && !(*spacing > 0)) throw py::value_error("spacing: " + num(*spacing) + "; expected > 0 (world units)");
  if (radius && !(*radius > 0))
    throw py::value_error("radius: " + num(*radius) + "; expected > 0 (world units) or None (auto)");
  if (upsample && (*upsample < 1 || *upsample > 8))
    throw py::value_error("upsample: " + std::to_string(*upsample) + "; expected 1 to 8 or None (auto)");
  if (hmin && !(*hmin > 0)) throw py::value_error("hmin: " + num(*hmin) + "; expected > 0 (world units)");
  const pm::Volume v = to_volume(array, "array", Values::any, to_geometry(origin, voxel_spacing, directions));
  pm::SurfacePipelineParams p;
  p.iso = iso;
  p.labels = std::move(labels);
  p.stencil = stencil;
  p.min_component = min_component;
  p.radius = radius.value_or(0);
  p.upsample = upsample.value_or(0);
  p.eps = eps;
  p.delta = delta;
  p.spacing = spacing.value_or(0);
  p.hmin = hmin.value_or(0);
  p.morph = morph;
  p.tighten = tighten;
  p.decimate = decimate;
  p.tolerance = tolerance;
  p.improve = improve;
  p.seed = seed;
  Run run(std::move(progress), threads);
  const pm::SurfacePipelineResult r = run([&] { return pm::mesh_surface_pipeline(v, p, "array"); });
  py::dict d = mesh_dict(r.surface);
  d["particles"] = mesh_dict(r.particles);
  if (tetrahedra) d["tetrahedra"] = tets_dict(r.tets, 0);
  d["kind"] = r.kind;
  d["warnings"] = warnings_list(r.warnings, run);
  d["seconds"] = seconds_dict(r.seconds);
  return d;
}

py::dict mesh_materials(const py::array& labels, const py::object& origin, const py::object& voxel_spacing,
                        const py::object& directions, const std::string& merge, std::size_t min_voxels,
                        long pad, const std::string& pad_value, const std::string& morph_ops, int downsample,
                        std::optional<double> radius, std::optional<int> upsample, double eps, double delta,
                        std::optional<double> hmin, const std::string& ma_side,
                        std::optional<double> spacing, int decimate, int improve, bool tetrahedra, std::uint64_t seed,
                        int threads, py::object progress) {
  if (spacing && !(*spacing > 0)) throw py::value_error("spacing: " + num(*spacing) + "; expected > 0 (world units)");
  if (radius && !(*radius > 0))
    throw py::value_error("radius: " + num(*radius) + "; expected > 0 (world units) or None (auto)");
  if (upsample && (*upsample < 1 || *upsample > 8))
    throw py::value_error("upsample: " + std::to_string(*upsample) + "; expected 1 to 8 or None (auto)");
  if (hmin && !(*hmin >= 0)) throw py::value_error("hmin: " + num(*hmin) + "; expected >= 0 (world units)");
  if (pad < -1) throw py::value_error("pad: " + std::to_string(pad) + "; expected >= 0 voxels or \"auto\"");
  const pm::Volume v = to_volume(labels, "labels", Values::labels, to_geometry(origin, voxel_spacing, directions));
  pm::MaterialsPipelineParams p;
  p.merge = merge;
  p.min_voxels = min_voxels;
  p.pad = pad;
  p.pad_value = pad_value;
  p.morph_ops = morph_ops;
  p.downsample = downsample;
  p.radius = radius.value_or(0);
  p.upsample = upsample.value_or(0);
  p.eps = eps;
  p.delta = delta;
  p.hmin = hmin.value_or(-1);
  p.ma_side = ma_side;
  p.spacing = spacing.value_or(0);
  p.decimate = decimate;
  p.improve = improve;
  p.seed = seed;
  Run run(std::move(progress), threads);
  const pm::MaterialsPipelineResult r = run([&] { return pm::mesh_materials_pipeline(v, p, "labels"); });
  const pm::MaterialMeshes& mm = r.meshes.meshes;
  py::dict d = mesh_dict(mm.interfaces);
  py::list pairs;
  for (const auto& [a, b] : mm.pairs) pairs.append(py::make_tuple(a, b));
  d["label_pairs"] = pairs;
  py::dict surfaces;
  for (const auto& [l, m] : mm.surfaces) surfaces[py::int_(l)] = mesh_dict(m);
  d["surfaces"] = surfaces;
  d["outside_label"] = r.meshes.outside_label;
  d["particles"] = mesh_dict(r.particles);
  if (tetrahedra) d["tetrahedra"] = tets_dict(r.meshes.tets, r.meshes.outside_label);
  d["warnings"] = warnings_list(r.warnings, run);
  d["seconds"] = seconds_dict(r.seconds);
  return d;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "particlemesh's compiled core; use the particlemesh package";
  pm::set_tool_name("particlemesh");
  pm::set_verbosity(pm::Verbosity::quiet);  // warnings come back in the results
  m.attr("version") = PM_VERSION;

  // libcore's typed errors as Python's: bad values and bad data are
  // ValueError, file system failures OSError, a failed check RuntimeError.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const pm::UsageError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const pm::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const pm::IoError& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    } catch (const pm::Cancelled& e) {
      PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
    } catch (const pm::Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });

  m.def("read_volume", &read_volume, py::arg("path"));
  m.def("sample", &sample, py::arg("array"), py::arg("origin"), py::arg("voxel_spacing"), py::arg("directions"),
        py::arg("iso"), py::arg("spacing"), py::arg("density"), py::arg("alpha_cap"), py::arg("sizing"),
        py::arg("sizing_origin"), py::arg("sizing_spacing"), py::arg("sizing_directions"), py::arg("init"),
        py::arg("init_count"), py::arg("lattice_init"), py::arg("count"), py::arg("kernel"), py::arg("energy"),
        py::arg("tolerance"), py::arg("population_tolerance"), py::arg("population"), py::arg("max_iters"),
        py::arg("coarse_to_fine"), py::arg("coarse_start"), py::arg("thin_seeds"), py::arg("settle"),
        py::arg("seed"), py::arg("threads"),
        py::arg("progress"));
  m.def("mesh_surface", &mesh_surface, py::arg("array"), py::arg("origin"), py::arg("voxel_spacing"),
        py::arg("directions"), py::arg("iso"), py::arg("labels"), py::arg("stencil"), py::arg("min_component"),
        py::arg("radius"), py::arg("upsample"), py::arg("eps"), py::arg("delta"), py::arg("spacing"),
        py::arg("hmin"), py::arg("morph"), py::arg("tighten"), py::arg("decimate"), py::arg("tolerance"),
        py::arg("improve"), py::arg("tetrahedra"), py::arg("seed"), py::arg("threads"), py::arg("progress"));
  m.def("mesh_materials", &mesh_materials, py::arg("labels"), py::arg("origin"), py::arg("voxel_spacing"),
        py::arg("directions"), py::arg("merge"), py::arg("min_voxels"), py::arg("pad"), py::arg("pad_value"),
        py::arg("morph_ops"), py::arg("downsample"), py::arg("radius"), py::arg("upsample"), py::arg("eps"),
        py::arg("delta"), py::arg("hmin"), py::arg("ma_side"), py::arg("spacing"), py::arg("decimate"),
        py::arg("improve"), py::arg("tetrahedra"), py::arg("seed"), py::arg("threads"), py::arg("progress"));
}

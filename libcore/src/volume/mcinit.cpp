#include "pm/volume/mcinit.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/field/kernels.h"
#include "pm/volume/labels.h"

namespace pm {
namespace {

/// Node values of the reconstructed field: the separable 3-tap filter
/// (f(1), f(0), f(1)) of the value kernel, border replicated like VolumeField.
std::vector<float> resample_nodes(const Volume& v, KernelType kernel) {
  const Dims d = v.dims();
  std::vector<float> a = v.to_float();
  const double w0 = kernel_value(kernel, 0.0), w1 = kernel_value(kernel, 1.0);
  if (w1 == 0.0 && w0 == 1.0) return a;  // interpolating kernel: the voxels themselves
  std::vector<float> b(a.size());
  const std::size_t stride[3] = {1, d.nx, d.nx * d.ny};
  for (int axis = 0; axis < 3; ++axis) {
    const std::size_t n = d[axis], s = stride[axis];
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, d.nz), [&](const tbb::blocked_range<std::size_t>& zr) {
      for (std::size_t k = zr.begin(); k != zr.end(); ++k)
        for (std::size_t j = 0; j < d.ny; ++j)
          for (std::size_t i = 0; i < d.nx; ++i) {
            const std::size_t v0 = i + d.nx * (j + d.ny * k);
            const std::size_t c = axis == 0 ? i : (axis == 1 ? j : k);
            const float lo = a[c > 0 ? v0 - s : v0], hi = a[c + 1 < n ? v0 + s : v0];
            b[v0] = float(w1 * (double(lo) + double(hi)) + w0 * double(a[v0]));
          }
    });
    a.swap(b);
  }
  return a;
}

struct UnionFind {
  std::vector<std::uint32_t> parent;
  std::uint32_t find(std::uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

struct KeyHash {
  std::size_t operator()(const std::array<std::int64_t, 7>& k) const {
    std::size_t h = 1469598103934665603ull;
    for (auto x : k) h = (h ^ std::size_t(x)) * 1099511628211ull;
    return h;
  }
};

/// Indices of the seeds to keep: per key (label set or component) and block of
/// k^3 cells, the seed nearest the block centre (index space); ties -> first.
std::vector<std::size_t> decimate(const std::vector<Vec3>& ijk, const std::vector<std::array<std::int64_t, 4>>& keys,
                                  int k) {
  std::vector<std::size_t> keep;
  if (k <= 1) {
    keep.resize(ijk.size());
    std::iota(keep.begin(), keep.end(), std::size_t(0));
    return keep;
  }
  std::unordered_map<std::array<std::int64_t, 7>, std::size_t, KeyHash> best;
  auto dist2 = [&](std::size_t s) {
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double c = (std::floor(ijk[s][a] / k) + 0.5) * k - 0.5;
      d2 += (ijk[s][a] - c) * (ijk[s][a] - c);
    }
    return d2;
  };
  for (std::size_t s = 0; s < ijk.size(); ++s) {
    std::array<std::int64_t, 7> key{keys[s][0], keys[s][1], keys[s][2], keys[s][3],
                                    std::int64_t(std::floor(ijk[s].x / k)), std::int64_t(std::floor(ijk[s].y / k)),
                                    std::int64_t(std::floor(ijk[s].z / k))};
    auto [it, fresh] = best.emplace(key, s);
    if (!fresh && dist2(s) < dist2(it->second)) it->second = s;
  }
  keep.reserve(best.size());
  for (const auto& [key, s] : best) keep.push_back(s);
  std::sort(keep.begin(), keep.end());
  return keep;
}

void check_grid(const Volume& v, const char* who) {
  const Dims d = v.dims();
  if (d.nx < 2 || d.ny < 2 || d.nz < 2) {
    std::ostringstream m;
    m << who << ": volume " << d.nx << "x" << d.ny << "x" << d.nz << " has an axis with one node; expected >= 2 per axis";
    throw InputError(m.str());
  }
}

}  // namespace

McInitResult mc_seeds(const Volume& v, const McInitParams& p) {
  if (p.decimate < 1) throw UsageError("mc_seeds: decimate " + std::to_string(p.decimate) + "; expected >= 1");
  check_grid(v, "mc_seeds");
  require_finite(v, "mc_seeds");
  const ValueRange range = value_range(v);
  if (!(p.iso >= range.lo && p.iso <= range.hi)) {
    std::ostringstream m;
    m << "no surface: the isovalue " << p.iso << " is outside the value range [" << range.lo << ", " << range.hi << "]";
    throw InputError(m.str());
  }
  const Dims d = v.dims();
  const std::vector<float> f = resample_nodes(v, p.field.value_kernel);
  const float iso = float(p.iso);
  auto inside = [&](std::size_t n) { return f[n] < iso; };
  const std::size_t sy = d.nx, sz = d.nx * d.ny;

  // Crossing edges, per z slice in order (deterministic).
  struct Seed {
    Vec3 ijk;
    std::size_t cell;  // a crossing cell containing the edge
  };
  std::vector<std::vector<Seed>> slices(d.nz);
  const std::size_t cx = d.nx - 1, cy = d.ny - 1;
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, d.nz), [&](const tbb::blocked_range<std::size_t>& zr) {
    for (std::size_t k = zr.begin(); k != zr.end(); ++k)
      for (std::size_t j = 0; j < d.ny; ++j)
        for (std::size_t i = 0; i < d.nx; ++i) {
          const std::size_t n = i + sy * j + sz * k;
          const std::size_t c[3] = {i, j, k};
          const std::size_t step[3] = {1, sy, sz};
          for (int a = 0; a < 3; ++a) {
            if (c[a] + 1 >= d[a] || inside(n) == inside(n + step[a])) continue;
            const double fa = f[n], fb = f[n + step[a]];
            const double t = (double(iso) - fa) / (fb - fa);
            Vec3 x{double(i), double(j), double(k)};
            x[a] += t;
            // A cell containing the edge: lower corner clamped to the cell range.
            const std::size_t ci = std::min(i, cx - 1), cj = std::min(j, cy - 1), ck = std::min(k, d.nz - 2);
            slices[k].push_back({x, ci + cx * (cj + cy * ck)});
          }
        }
  });
  std::vector<Seed> seeds;
  for (auto& s : slices) seeds.insert(seeds.end(), s.begin(), s.end());
  slices.clear();
  if (seeds.empty()) {
    std::ostringstream m;
    m << "no surface: no grid edge crosses the isovalue " << p.iso << " (value range [" << range.lo << ", "
      << range.hi << "])";
    throw InputError(m.str());
  }

  // Components of crossing cells, joined through faces with a sign change.
  const std::size_t ncells = cx * cy * (d.nz - 1);
  if (ncells >= std::size_t(0xFFFFFFFFu)) throw InputError("mc_seeds: volume too large (more than 2^32 cells)");
  UnionFind uf;
  uf.parent.resize(ncells);
  std::iota(uf.parent.begin(), uf.parent.end(), 0u);
  std::vector<std::uint8_t> crossing(ncells, 0);
  auto corner = [&](std::size_t i, std::size_t j, std::size_t k) { return inside(i + sy * j + sz * k); };
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, d.nz - 1), [&](const tbb::blocked_range<std::size_t>& zr) {
    for (std::size_t k = zr.begin(); k != zr.end(); ++k)
      for (std::size_t j = 0; j < cy; ++j)
        for (std::size_t i = 0; i < cx; ++i) {
          int in = 0;
          for (int c = 0; c < 8; ++c) in += corner(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
          crossing[i + cx * (j + cy * k)] = in > 0 && in < 8;
        }
  });
  for (std::size_t k = 0; k + 1 < d.nz; ++k)
    for (std::size_t j = 0; j < cy; ++j)
      for (std::size_t i = 0; i < cx; ++i) {
        const std::size_t c = i + cx * (j + cy * k);
        if (!crossing[c]) continue;
        // The face shared with the +a neighbour: the 4 nodes at offset 1 along a.
        for (int a = 0; a < 3; ++a) {
          const std::size_t lim[3] = {cx, cy, d.nz - 1};
          const std::size_t pos[3] = {i, j, k};
          if (pos[a] + 1 >= lim[a]) continue;
          const std::size_t nb = c + (a == 0 ? 1 : (a == 1 ? cx : cx * cy));
          if (!crossing[nb]) continue;
          int in = 0;
          for (int q = 0; q < 4; ++q) {
            std::size_t o[3] = {i, j, k};
            o[a] += 1;
            o[(a + 1) % 3] += std::size_t(q & 1);
            o[(a + 2) % 3] += std::size_t((q >> 1) & 1);
            in += corner(o[0], o[1], o[2]);
          }
          if (in > 0 && in < 4) uf.unite(std::uint32_t(c), std::uint32_t(nb));
        }
      }
  std::unordered_map<std::uint32_t, std::int64_t> comp_id;
  std::vector<std::int64_t> comp(seeds.size());
  for (std::size_t s = 0; s < seeds.size(); ++s) {
    const std::uint32_t root = uf.find(std::uint32_t(seeds[s].cell));
    comp[s] = comp_id.emplace(root, std::int64_t(comp_id.size())).first->second;
  }
  McInitResult res;
  res.crossings = seeds.size();
  res.components = comp_id.size();
  uf.parent.clear();
  uf.parent.shrink_to_fit();

  // Decimation per component.
  std::vector<Vec3> ijk(seeds.size());
  std::vector<std::array<std::int64_t, 4>> keys(seeds.size());
  for (std::size_t s = 0; s < seeds.size(); ++s) {
    ijk[s] = seeds[s].ijk;
    keys[s] = {comp[s], 0, 0, 0};
  }
  const std::vector<std::size_t> keep = decimate(ijk, keys, p.decimate);

  // Projection onto F = c of the reconstructed field, normals from its gradient.
  const VolumeField field(v, p.field);
  const Geometry& g = v.geometry();
  double diag = 0;
  for (int a = 0; a < 3; ++a) diag += g.spacing(a) * g.spacing(a);
  diag = std::sqrt(diag);
  const double tol = 1e-6 * (std::fabs(p.iso) + (range.hi - range.lo));
  Mesh& m = res.seeds;
  m.vertices.resize(keep.size());
  m.normals.resize(keep.size());
  std::vector<double>& comp_out = m.vertex_scalars["component"];
  comp_out.resize(keep.size());
  std::vector<std::uint8_t> on_surface(keep.size(), 0);
  std::vector<double> resid(keep.size(), 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, keep.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t q = r.begin(); q != r.end(); ++q) {
      const std::size_t s = keep[q];
      const Vec3 x0 = g.index_to_world(ijk[s]);
      Vec3 x = x0, grad;
      double fx = field.value_gradient(x, grad);
      for (int it = 0; it < p.project_steps && std::fabs(fx - p.iso) > tol; ++it) {
        const double g2 = norm2(grad);
        if (!(g2 > 0)) break;
        x -= ((fx - p.iso) / g2) * grad;
        fx = field.value_gradient(x, grad);
      }
      const bool ok = p.project_steps > 0 && std::fabs(fx - p.iso) <= tol && norm(x - x0) <= diag && is_finite(x);
      if (!ok) {
        x = x0;
        fx = field.value_gradient(x, grad);
      }
      m.vertices[q] = x;
      m.normals[q] = normalized(grad);
      comp_out[q] = double(comp[s]);
      on_surface[q] = ok;
      resid[q] = std::fabs(fx - p.iso);
    }
  });
  for (std::size_t q = 0; q < keep.size(); ++q) {
    res.projected += on_surface[q];
    res.max_residual = std::max(res.max_residual, resid[q]);
  }
  return res;
}

JunctionResult junction_seeds(const Volume& labels, const JunctionParams& p) {
  if (p.decimate < 1) throw UsageError("junction_seeds: decimate " + std::to_string(p.decimate) + "; expected >= 1");
  check_grid(labels, "junction_seeds");
  require_labels(labels, "junction_seeds");
  const Dims d = labels.dims();
  // Dense label indices (sorted label order).
  std::vector<std::int64_t> values;
  std::vector<std::uint16_t> idx(labels.count());
  {
    std::unordered_map<std::int64_t, std::uint16_t> ids;
    std::int64_t last = 0;
    int last_id = -1;
    for (std::size_t i = 0; i < idx.size(); ++i) {
      const auto val = std::int64_t(labels.get(i));
      if (last_id < 0 || val != last) {
        auto it = ids.find(val);
        if (it == ids.end()) {
          if (val < 0)
            throw InputError("junction_seeds: label " + std::to_string(val) + " is negative; expected labels >= 0");
          if (values.size() >= 0xFFFF) throw InputError("junction_seeds: more than 65535 labels; expected a label map");
          it = ids.emplace(val, std::uint16_t(values.size())).first;
          values.push_back(val);
        }
        last = val;
        last_id = it->second;
      }
      idx[i] = std::uint16_t(last_id);
    }
    if (values.size() < 2)
      throw InputError("junction_seeds: the label map holds a single label (" + std::to_string(values[0]) +
                       "); expected at least 2 materials");
    std::vector<std::int64_t> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    std::vector<std::uint16_t> remap(values.size());
    for (std::size_t a = 0; a < values.size(); ++a)
      remap[a] = std::uint16_t(std::lower_bound(sorted.begin(), sorted.end(), values[a]) - sorted.begin());
    for (auto& x : idx) x = remap[x];
    values = std::move(sorted);
  }

  struct JSeed {
    Vec3 ijk;
    std::array<int, 4> set;  // sorted label indices, -1 where unused
    int axis;                // pair seeds: edge axis; -1 otherwise
    int sign;                // pair seeds: +1 if set[0]'s node is the lower one
  };
  const std::size_t sy = d.nx, sz = d.nx * d.ny;
  std::vector<std::vector<JSeed>> slices(d.nz);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, d.nz), [&](const tbb::blocked_range<std::size_t>& zr) {
    for (std::size_t k = zr.begin(); k != zr.end(); ++k) {
      auto& out = slices[k];
      for (std::size_t j = 0; j < d.ny; ++j)
        for (std::size_t i = 0; i < d.nx; ++i) {
          const std::size_t n = i + sy * j + sz * k;
          const std::size_t c[3] = {i, j, k};
          const std::size_t step[3] = {1, sy, sz};
          for (int a = 0; a < 3; ++a) {
            if (c[a] + 1 >= d[a] || idx[n] == idx[n + step[a]]) continue;
            const int la = idx[n], lb = idx[n + step[a]];
            Vec3 x{double(i), double(j), double(k)};
            x[a] += 0.5;
            out.push_back({x, {std::min(la, lb), std::max(la, lb), -1, -1}, a, la < lb ? 1 : -1});
          }
          if (i + 1 >= d.nx || j + 1 >= d.ny || k + 1 >= d.nz) continue;
          std::array<int, 8> cl;
          for (int q = 0; q < 8; ++q)
            cl[q] = idx[n + std::size_t(q & 1) + sy * std::size_t((q >> 1) & 1) + sz * std::size_t((q >> 2) & 1)];
          std::sort(cl.begin(), cl.end());
          const auto end = std::unique(cl.begin(), cl.end());
          const int distinct = int(end - cl.begin());
          if (distinct < 3) continue;
          JSeed s{Vec3(i + 0.5, j + 0.5, k + 0.5), {cl[0], cl[1], cl[2], distinct >= 4 ? cl[3] : -1}, -1, 0};
          out.push_back(s);
        }
    }
  });
  std::vector<JSeed> seeds;
  for (auto& s : slices) seeds.insert(seeds.end(), s.begin(), s.end());
  slices.clear();

  std::vector<Vec3> ijk(seeds.size());
  std::vector<std::array<std::int64_t, 4>> keys(seeds.size());
  for (std::size_t s = 0; s < seeds.size(); ++s) {
    ijk[s] = seeds[s].ijk;
    for (int a = 0; a < 4; ++a) keys[s][a] = seeds[s].set[a];
  }
  const std::vector<std::size_t> keep = decimate(ijk, keys, p.decimate);

  JunctionResult res;
  Mesh& m = res.seeds;
  const Geometry& g = labels.geometry();
  const char* names[4] = {"label_a", "label_b", "label_c", "label_d"};
  std::array<std::vector<double>*, 4> lab;
  for (int a = 0; a < 4; ++a) lab[a] = &m.vertex_scalars[names[a]];
  std::vector<double>& junction = m.vertex_scalars["junction"];
  for (std::size_t s : keep) {
    const JSeed& q = seeds[s];
    m.vertices.push_back(g.index_to_world(q.ijk));
    m.normals.push_back(q.axis >= 0 ? normalized(g.directions.column(q.axis)) * double(q.sign) : Vec3());
    int count = 0;
    for (int a = 0; a < 4; ++a) {
      lab[a]->push_back(q.set[a] >= 0 ? double(values[std::size_t(q.set[a])]) : -1.0);
      count += q.set[a] >= 0;
    }
    junction.push_back(double(count));
    if (count == 2)
      ++res.pairs[{values[std::size_t(q.set[0])], values[std::size_t(q.set[1])]}];
    else if (count == 3)
      ++res.triples;
    else
      ++res.quadruples;
  }
  return res;
}

}  // namespace pm

#include "pm/mesh/coverage.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "pm/base/error.h"

namespace pm {

namespace {

// Uniform grid over the seeds for nearest-seed queries.
class SeedGrid {
 public:
  explicit SeedGrid(const std::vector<Vec3>& pts) : pts_(pts) {
    for (const Vec3& p : pts) box_.extend(p);
    const Vec3 s = box_.size();
    const double vol = std::max(s.x, 1e-12) * std::max(s.y, 1e-12) * std::max(s.z, 1e-12);
    cell_ = std::cbrt(vol / double(pts.size())) * 2;
    const double diag = norm(s);
    cell_ = std::max(cell_, diag / 256 + 1e-12);
    for (int a = 0; a < 3; ++a) n_[a] = std::max(1, int(std::ceil(s[a] / cell_)) + 1);
    start_.assign(std::size_t(n_[0]) * std::size_t(n_[1]) * std::size_t(n_[2]) + 1, 0);
    std::vector<std::size_t> key(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) key[i] = cell_index(pts[i]), ++start_[key[i] + 1];
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(pts.size());
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < pts.size(); ++i) items_[fill[key[i]]++] = i;
  }

  std::size_t nearest(const Vec3& x) const {
    int c[3];
    for (int a = 0; a < 3; ++a) c[a] = clamp_cell(x, a);
    // Distance from x to the grid box, so rings are measured from where x enters it.
    double out = 0;
    for (int a = 0; a < 3; ++a) {
      const double d = std::max({box_.lo[a] - x[a], 0.0, x[a] - box_.hi[a]});
      out += d * d;
    }
    out = std::sqrt(out);
    std::size_t best = 0;
    double bd = 1e300;
    const int rmax = std::max({n_[0], n_[1], n_[2]});
    for (int r = 0; r <= rmax; ++r) {
      for (int k = c[2] - r; k <= c[2] + r; ++k)
        for (int j = c[1] - r; j <= c[1] + r; ++j)
          for (int i = c[0] - r; i <= c[0] + r; ++i) {
            if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) != r) continue;
            if (i < 0 || j < 0 || k < 0 || i >= n_[0] || j >= n_[1] || k >= n_[2]) continue;
            const std::size_t cell = std::size_t(i) + std::size_t(n_[0]) * (std::size_t(j) + std::size_t(n_[1]) * std::size_t(k));
            for (std::size_t t = start_[cell]; t < start_[cell + 1]; ++t) {
              const std::size_t s = items_[t];
              const double d = norm(pts_[s] - x);
              if (d < bd || (d == bd && s < best)) bd = d, best = s;
            }
          }
      // A seed not yet visited is more than r cells away along some axis, so
      // at least r cell widths from x, and never nearer than the box.
      if (bd <= std::max(out, r * cell_)) break;
    }
    return best;
  }

 private:
  int clamp_cell(const Vec3& x, int a) const {
    return std::clamp(int(std::floor((x[a] - box_.lo[a]) / cell_)), 0, n_[a] - 1);
  }
  std::size_t cell_index(const Vec3& x) const {
    return std::size_t(clamp_cell(x, 0)) +
           std::size_t(n_[0]) * (std::size_t(clamp_cell(x, 1)) + std::size_t(n_[1]) * std::size_t(clamp_cell(x, 2)));
  }
  const std::vector<Vec3>& pts_;
  Box box_;
  double cell_ = 1;
  int n_[3] = {1, 1, 1};
  std::vector<std::size_t> start_, items_;
};

}  // namespace

std::vector<ComponentCoverage> component_coverage(const Mesh& seeds, const std::vector<Vec3>& points) {
  auto it = seeds.vertex_scalars.find("component");
  if (it == seeds.vertex_scalars.end())
    throw InputError("component coverage: the seeds have no vertex property \"component\"; expected mcinit's output");
  if (seeds.vertices.empty()) throw InputError("component coverage: no seeds");
  std::map<int, ComponentCoverage> by;
  for (std::size_t i = 0; i < seeds.vertices.size(); ++i) {
    ComponentCoverage& c = by[int(it->second[i])];
    c.component = int(it->second[i]);
    ++c.seeds;
    c.bounds.extend(seeds.vertices[i]);
  }
  const SeedGrid grid(seeds.vertices);
  // Nearest seeds in parallel, counted per component in a dense table per
  // chunk and summed (integers: the same counts for any schedule).
  std::vector<int> comps;
  for (const auto& kv : by) comps.push_back(kv.first);
  std::vector<std::size_t> slot(seeds.vertices.size());
  for (std::size_t i = 0; i < seeds.vertices.size(); ++i)
    slot[i] = std::size_t(std::lower_bound(comps.begin(), comps.end(), int(it->second[i])) - comps.begin());
  const std::vector<std::size_t> counts = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, points.size(), 4096), std::vector<std::size_t>(comps.size(), 0),
      [&](const tbb::blocked_range<std::size_t>& r, std::vector<std::size_t> acc) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) ++acc[slot[grid.nearest(points[i])]];
        return acc;
      },
      [](std::vector<std::size_t> a, const std::vector<std::size_t>& b) {
        for (std::size_t c = 0; c < a.size(); ++c) a[c] += b[c];
        return a;
      });
  for (std::size_t c = 0; c < comps.size(); ++c) by[comps[c]].points += counts[c];
  std::vector<ComponentCoverage> out;
  for (auto& kv : by) out.push_back(kv.second);
  return out;
}

}  // namespace pm

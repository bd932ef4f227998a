// Throughput of VolumeField reconstruction on a 256³ float field (the
// particle system's hot path). Items = evaluations; the target is >= 10 M
// value+gradient evaluations per second per core.
//
// Arguments: mix = 0 cubic B-spline for value and derivatives, 1 Chapter-5
// mix (Catmull-Rom value, B-spline derivatives); walk = 0 uniformly random
// points over the whole 64 MiB field (every evaluation misses the caches:
// bound by memory latency), 1 a random walk with one-voxel steps (coherent
// like consecutive particles; bound by arithmetic).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "pm/base/volume.h"
#include "pm/field/volume_field.h"

namespace {

constexpr std::size_t kN = 256;
constexpr double kSpacing = 0.5;
constexpr std::size_t kPoints = std::size_t(1) << 20;  // power of two: index wraps with a mask

// A smooth sum of sines on a 256³ grid, world box [0, 127.5]³.
const pm::Volume& test_volume() {
  static const pm::Volume vol = [] {
    pm::Volume v(pm::VoxelType::f32, pm::Dims{kN, kN, kN},
                 pm::Geometry::with_spacing(kSpacing, kSpacing, kSpacing));
    float* d = v.data<float>();
    std::vector<double> sx(kN), sy(kN), sz(kN);
    for (std::size_t i = 0; i < kN; ++i) {
      sx[i] = std::sin(0.11 * double(i));
      sy[i] = std::sin(0.07 * double(i) + 1.0);
      sz[i] = std::sin(0.05 * double(i) + 2.0);
    }
    for (std::size_t k = 0; k < kN; ++k)
      for (std::size_t j = 0; j < kN; ++j)
        for (std::size_t i = 0; i < kN; ++i)
          d[v.index(i, j, k)] = float(sx[i] + sy[j] + sz[k] + 0.5 * sx[i] * sy[j] * sz[k]);
    return v;
  }();
  return vol;
}

const pm::VolumeField& field(bool mix) {
  static const pm::VolumeField bspline(test_volume(), pm::VolumeFieldParams{}, "bench");
  static const pm::VolumeField chapter5(test_volume(), pm::VolumeFieldParams::chapter5_mix(), "bench");
  return mix ? chapter5 : bspline;
}

const std::vector<pm::Vec3>& points(bool walk) {
  static const std::vector<pm::Vec3> uniform = [] {
    std::mt19937_64 rng(12345);
    const pm::Box b = field(false).domain();
    std::uniform_real_distribution<double> ux(b.lo.x, b.hi.x), uy(b.lo.y, b.hi.y), uz(b.lo.z, b.hi.z);
    std::vector<pm::Vec3> p(kPoints);
    for (auto& x : p) x = pm::Vec3(ux(rng), uy(rng), uz(rng));
    return p;
  }();
  static const std::vector<pm::Vec3> random_walk = [] {
    std::mt19937_64 rng(54321);
    std::normal_distribution<double> step(0.0, kSpacing / std::sqrt(3.0));  // ~1 voxel per step
    const pm::Box b = field(false).domain();
    std::vector<pm::Vec3> p(kPoints);
    pm::Vec3 x = (b.lo + b.hi) * 0.5;
    for (auto& q : p) {
      for (int a = 0; a < 3; ++a) {
        x[a] += step(rng);
        if (x[a] < b.lo[a] || x[a] > b.hi[a]) x[a] = 0.5 * (b.lo[a] + b.hi[a]);
      }
      q = x;
    }
    return p;
  }();
  return walk ? random_walk : uniform;
}

void BM_value(benchmark::State& state) {
  const pm::VolumeField& f = field(state.range(0) != 0);
  const auto& pts = points(state.range(1) != 0);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.value(pts[i]));
    i = (i + 1) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_value_gradient(benchmark::State& state) {
  const pm::VolumeField& f = field(state.range(0) != 0);
  const auto& pts = points(state.range(1) != 0);
  std::size_t i = 0;
  pm::Vec3 g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.value_gradient(pts[i], g));
    benchmark::DoNotOptimize(g);
    i = (i + 1) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_evaluate(benchmark::State& state) {
  const pm::VolumeField& f = field(state.range(0) != 0);
  const auto& pts = points(state.range(1) != 0);
  std::size_t i = 0;
  pm::Vec3 g;
  pm::Mat3 h;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.evaluate(pts[i], g, h));
    benchmark::DoNotOptimize(g);
    benchmark::DoNotOptimize(h);
    i = (i + 1) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations());
}

BENCHMARK(BM_value)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
BENCHMARK(BM_value_gradient)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
BENCHMARK(BM_evaluate)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});

}  // namespace

BENCHMARK_MAIN();

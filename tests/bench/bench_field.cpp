// Throughput of VolumeField reconstruction on a 256³ float field (the
// particle system's hot path). Items = evaluations; the target is >= 10 M
// value+gradient evaluations per second per core.
//
// Arguments: mix = 0 cubic B-spline for value and derivatives, 1 Chapter-5
// mix (Catmull-Rom value, B-spline derivatives); walk = 0 uniformly random
// points over the whole 64 MiB field (every evaluation misses the caches:
// bound by memory latency), 1 a random walk with one-voxel steps (coherent
// like consecutive particles; bound by arithmetic).
//
// BM_*_batch: the same points through the batch calls, kBatch per call
// (BM_value_batch) or `batch` per call, with and without evaluation in brick
// order (`sort`: 0 never, 1 always, 2 default; VolumeFieldParams::sort_min_batch).
// BM_value_gradient_baseline_isa: with the AVX2 path disabled (what a CPU
// without AVX2 runs). BM_random_lines: the machine's ceiling for random
// access, independent 64-byte lines fetched from a 64 MiB buffer with
// software prefetch `ahead` lines in advance (items = lines); one
// evaluation at a random point touches ~10.9 lines (1.75 x 2.5 x 2.5 bricks).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <vector>

#ifdef __linux__
#include <sys/mman.h>
#endif

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

// sort = 0: batches never evaluated in brick order (the points' own order);
// 1: always (sort_min_batch = 2); 2: the default (sort_min_batch = 0: from
// 262144 points on this 256³ field, unless the points are coherent already).
const pm::VolumeField& field(bool mix, int sort) {
  if (sort == 2) return field(mix);
  static const auto with = [](pm::VolumeFieldParams p, std::size_t sort_min) {
    p.sort_min_batch = sort_min;
    return p;
  };
  static const pm::VolumeField never[2] = {
      pm::VolumeField(test_volume(), with({}, SIZE_MAX), "bench"),
      pm::VolumeField(test_volume(), with(pm::VolumeFieldParams::chapter5_mix(), SIZE_MAX), "bench")};
  static const pm::VolumeField always[2] = {
      pm::VolumeField(test_volume(), with({}, 2), "bench"),
      pm::VolumeField(test_volume(), with(pm::VolumeFieldParams::chapter5_mix(), 2), "bench")};
  return sort ? always[mix] : never[mix];
}

const pm::VolumeField& baseline_isa_field() {
  static const pm::VolumeField f(test_volume(), [] {
    pm::VolumeFieldParams p;
    p.allow_avx2 = false;
    return p;
  }(), "bench");
  return f;
}

constexpr std::size_t kBatch = 256;  // points per batch call (divides kPoints)

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

void BM_value_batch(benchmark::State& state) {
  const pm::VolumeField& f = field(state.range(0) != 0);
  const auto& pts = points(state.range(1) != 0);
  std::vector<double> v(kBatch);
  std::size_t i = 0;
  for (auto _ : state) {
    f.value_batch(&pts[i], kBatch, v.data());
    benchmark::DoNotOptimize(v.data());
    benchmark::ClobberMemory();
    i = (i + kBatch) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}

void value_gradient_batch(benchmark::State& state, const pm::VolumeField& f, bool walk,
                          std::size_t batch = kBatch) {
  const auto& pts = points(walk);
  std::vector<double> v(batch);
  std::vector<pm::Vec3> g(batch);
  std::size_t i = 0;
  for (auto _ : state) {
    f.value_gradient_batch(&pts[i], batch, v.data(), g.data());
    benchmark::DoNotOptimize(v.data());
    benchmark::DoNotOptimize(g.data());
    benchmark::ClobberMemory();
    i = (i + batch) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations() * batch);
}

// Batches of `batch` points (a power of two up to kPoints, consecutive
// slices of the same point set), sorted into brick order or not (`sort`);
// the sort runs inside the timed call.
void BM_value_gradient_batch(benchmark::State& state) {
  value_gradient_batch(state, field(state.range(0) != 0, int(state.range(3))), state.range(1) != 0,
                       std::size_t(state.range(2)));
}

void BM_evaluate_batch(benchmark::State& state) {
  const pm::VolumeField& f = field(state.range(0) != 0, int(state.range(3)));
  const auto& pts = points(state.range(1) != 0);
  const std::size_t batch = std::size_t(state.range(2));
  std::vector<double> v(batch);
  std::vector<pm::Vec3> g(batch);
  std::vector<pm::Mat3> h(batch);
  std::size_t i = 0;
  for (auto _ : state) {
    f.evaluate_batch(&pts[i], batch, v.data(), g.data(), h.data());
    benchmark::DoNotOptimize(v.data());
    benchmark::DoNotOptimize(g.data());
    benchmark::DoNotOptimize(h.data());
    benchmark::ClobberMemory();
    i = (i + batch) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations() * batch);
}

// B-spline value+gradient without the AVX2 path, single points (batch:0)
// or batches of 256 (batch:256).
void BM_value_gradient_baseline_isa(benchmark::State& state) {
  const pm::VolumeField& f = baseline_isa_field();
  const bool walk = state.range(1) != 0;
  if (state.range(2) != 0) return value_gradient_batch(state, f, walk, std::size_t(state.range(2)));
  const auto& pts = points(walk);
  std::size_t i = 0;
  pm::Vec3 g;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.value_gradient(pts[i], g));
    benchmark::DoNotOptimize(g);
    i = (i + 1) & (kPoints - 1);
  }
  state.SetItemsProcessed(state.iterations());
}

// 64 MiB of lines (as large as the 256³ float field), on huge pages when
// Linux grants them (VolumeField asks for them too), touched once.
const float* line_buffer() {
  static const float* buf = [] {
    constexpr std::size_t bytes = std::size_t(64) << 20;
    auto* p = static_cast<float*>(std::aligned_alloc(std::size_t(2) << 20, bytes));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(p, bytes, MADV_HUGEPAGE);
#endif
    for (std::size_t i = 0; i < bytes / sizeof(float); ++i) p[i] = float(i & 255);
    return p;
  }();
  return buf;
}

void BM_random_lines(benchmark::State& state) {
  constexpr std::size_t kLines = (std::size_t(64) << 20) / 64, kStream = std::size_t(1) << 22;
  static const std::vector<std::uint32_t> line = [] {
    std::mt19937 rng(777);
    std::vector<std::uint32_t> l(kStream);
    for (auto& x : l) x = std::uint32_t(rng() % kLines);
    return l;
  }();
  const float* buf = line_buffer();
  const std::size_t ahead = std::size_t(state.range(0));
  std::size_t i = 0;
  float sum = 0;
  for (auto _ : state) {
    for (std::size_t k = 0; k < 1024; ++k, ++i) {  // 1024 lines per iteration
#if defined(__GNUC__)
      if (ahead) __builtin_prefetch(buf + std::size_t(line[(i + ahead) & (kStream - 1)]) * 16);
#endif
      sum += buf[std::size_t(line[i & (kStream - 1)]) * 16];
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * 1024);
}

BENCHMARK(BM_value)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
BENCHMARK(BM_value_gradient)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
BENCHMARK(BM_evaluate)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
BENCHMARK(BM_value_batch)->ArgNames({"mix", "walk"})->ArgsProduct({{0, 1}, {0, 1}});
// Batch sizes: 256 (kBatch) as before, then 4k, 64k, 256k and 1M points
// (B-spline, random points) with and without the brick-order sort; the
// Chapter-5 mix at random points and the B-spline random walk at 1M; the
// default choice at 1M, random points and random walk.
constexpr std::int64_t kSizes[] = {4096, 65536, 262144, std::int64_t(kPoints)};
void batch_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"mix", "walk", "batch", "sort"});
  for (int mix : {0, 1})
    for (int walk : {0, 1}) b->Args({mix, walk, std::int64_t(kBatch), 0});
  for (std::int64_t n : kSizes)
    for (int sort : {0, 1}) b->Args({0, 0, n, sort});
  for (int sort : {0, 1}) b->Args({1, 0, std::int64_t(kPoints), sort});
  for (int sort : {0, 1, 2}) b->Args({0, 1, std::int64_t(kPoints), sort});
  b->Args({0, 0, std::int64_t(kPoints), 2});
}
BENCHMARK(BM_value_gradient_batch)->Apply(batch_args);
BENCHMARK(BM_evaluate_batch)->Apply(batch_args);
BENCHMARK(BM_value_gradient_baseline_isa)->ArgNames({"mix", "walk", "batch"})->ArgsProduct({{0}, {0, 1}, {0, std::int64_t(kBatch)}});
BENCHMARK(BM_random_lines)->ArgNames({"ahead"})->Arg(0)->Arg(8)->Arg(16)->Arg(32)->Arg(64);

}  // namespace

BENCHMARK_MAIN();

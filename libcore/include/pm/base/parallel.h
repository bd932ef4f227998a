// Parallel loops of libcore: pm::parallel_for over a tbb::blocked_range or an
// index range [first, last), with the semantics of tbb::parallel_for.
//
// Normal builds forward to TBB. ThreadSanitizer builds (PM_TSAN_THREADS,
// set by -DPM_TSAN=ON) run the same chunks on std::threads instead: Debian's
// libtbb is not instrumented, so TSan cannot see TBB hand work to its workers
// and back and reports every loop's fork and join as a race, which hides the
// races that matter (two iterations of one loop touching the same data).
// std::thread start and join are intercepted, so under TSan every report is
// about the loop bodies themselves. Results do not depend on the backend: the
// loops are written to be deterministic for any partition of the range.
#pragma once

#include <cstddef>
#include <exception>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#ifdef PM_TSAN_THREADS
#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include <tbb/global_control.h>
#endif

namespace pm {

#ifdef PM_TSAN_THREADS
namespace detail {
/// Runs run(lo, hi) for the chunks [0, n) split at `grain`, on at least two
/// std::threads (so that races can show even with --threads 1), chunks taken
/// in turn from a shared counter; the first exception is rethrown after join.
template <class Run>
void run_chunks_on_threads(std::size_t n, std::size_t grain, const Run& run) {
  if (n == 0) return;
  const std::size_t threads = std::max<std::size_t>(
      2, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  grain = std::max<std::size_t>({grain, 1, n / (8 * threads)});
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto work = [&] {
    for (;;) {
      const std::size_t lo = next.fetch_add(grain);
      if (lo >= n) return;
      try {
        run(lo, std::min(n, lo + grain));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
    }
  };
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}
}  // namespace detail
#endif

template <class T, class Body>
void parallel_for(const tbb::blocked_range<T>& range, const Body& body) {
#ifdef PM_TSAN_THREADS
  const T b = range.begin();
  detail::run_chunks_on_threads(std::size_t(range.end() - b), range.grainsize(), [&](std::size_t lo, std::size_t hi) {
    body(tbb::blocked_range<T>(T(b + T(lo)), T(b + T(hi)), range.grainsize()));
  });
#else
  tbb::parallel_for(range, body);
#endif
}

template <class I, class Body>
void parallel_for(I first, I last, const Body& body) {
#ifdef PM_TSAN_THREADS
  if (!(first < last)) return;
  detail::run_chunks_on_threads(std::size_t(last - first), 1, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) body(I(first + I(i)));
  });
#else
  tbb::parallel_for(first, last, body);
#endif
}

/// Runs task(i) for every i in [0, n) side by side (independent tasks such as
/// reading one file each). When tasks throw, the exception of the lowest i is
/// rethrown after all have finished, so the error a user sees does not depend
/// on the threads: the same one a loop in index order would have met first.
template <class Task>
void parallel_tasks(std::size_t n, const Task& task) {
  std::vector<std::exception_ptr> errors(n);
  pm::parallel_for(std::size_t(0), n, [&](std::size_t i) {
    try {
      task(i);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace pm

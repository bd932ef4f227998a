// pm::parallel_for (pm/base/parallel.h): every index of the range is visited
// exactly once, chunks stay inside the range, and an exception thrown by the
// body reaches the caller. Runs on TBB in normal builds and on std::threads
// under ThreadSanitizer (scripts/test --tsan), so both backends are checked.
#include <gtest/gtest.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "pm/base/parallel.h"

namespace pm {
namespace {

TEST(ParallelFor, BlockedRangeVisitsEveryIndexOnce) {
  for (const std::size_t grain : {std::size_t(1), std::size_t(7), std::size_t(5000)}) {
    std::vector<std::atomic<int>> hits(1003);
    pm::parallel_for(tbb::blocked_range<std::size_t>(3, 1003, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      ASSERT_LE(3u, r.begin());
      ASSERT_LE(r.end(), 1003u);
      for (std::size_t i = r.begin(); i != r.end(); ++i) hits[i].fetch_add(1);
    });
    for (std::size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(hits[i].load(), i < 3 ? 0 : 1) << i << " grain " << grain;
  }
  int calls = 0;
  pm::parallel_for(tbb::blocked_range<std::uint32_t>(5, 5), [&](const tbb::blocked_range<std::uint32_t>&) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, IndexRangeVisitsEveryIndexOnce) {
  std::vector<std::atomic<int>> hits(777);
  pm::parallel_for(std::size_t(1), std::size_t(777), [&](std::size_t i) { hits[i].fetch_add(1); });
  for (std::size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(hits[i].load(), i == 0 ? 0 : 1) << i;
  int calls = 0;
  pm::parallel_for(10, 3, [&](int) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, BodyExceptionReachesTheCaller) {
  EXPECT_THROW(pm::parallel_for(std::size_t(0), std::size_t(100),
                                [](std::size_t i) {
                                  if (i == 57) throw std::runtime_error("57");
                                }),
               std::runtime_error);
  EXPECT_THROW(pm::parallel_for(tbb::blocked_range<std::size_t>(0, 100),
                                [](const tbb::blocked_range<std::size_t>& r) {
                                  if (r.begin() <= 42 && 42 < r.end()) throw std::invalid_argument("42");
                                }),
               std::invalid_argument);
}

TEST(ParallelTasks, RunsEveryTaskAndRethrowsTheLowestFailure) {
  for (int round = 0; round < 20; ++round) {
    std::vector<std::atomic<int>> ran(64);
    try {
      pm::parallel_tasks(64, [&](std::size_t i) {
        ran[i].fetch_add(1);
        if (i == 41 || i == 17 || i == 63) throw std::runtime_error("task " + std::to_string(i));
      });
      ADD_FAILURE() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "task 17");  // the one a loop in index order meets first
    }
    for (std::size_t i = 0; i < ran.size(); ++i) EXPECT_EQ(ran[i].load(), 1) << i;  // the others still ran
  }
  int calls = 0;
  pm::parallel_tasks(0, [&](std::size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace pm

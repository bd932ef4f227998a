#pragma once
// Helpers shared by the unit tests.
#include <string>

namespace pm::test {

/// ../shared/data/<rel> if it exists, else "" (tests then GTEST_SKIP()).
std::string shared_data(const std::string& rel);
/// A fresh empty temporary folder for this test (removed at process exit).
std::string temp_dir();

}  // namespace pm::test

#define PM_REQUIRE_SHARED(var, rel)                                  \
  const std::string var = ::pm::test::shared_data(rel);             \
  if (var.empty()) GTEST_SKIP() << "shared data not present: " << rel

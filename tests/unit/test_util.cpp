#include "test_util.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;

namespace pm::test {

std::string shared_data(const std::string& rel) {
  const char* env = std::getenv("PM_SHARED_DATA");
  const fs::path root = env ? fs::path(env) : fs::path(PM_SHARED_DATA);
  const fs::path p = root / rel;
  return fs::exists(p) ? p.string() : std::string();
}

namespace {
struct TempRoot {
  fs::path root;
  TempRoot() {
    root = fs::temp_directory_path() / ("pm_tests_" + std::to_string(::getpid()));
    fs::create_directories(root);
  }
  ~TempRoot() {
    std::error_code ec;
    fs::remove_all(root, ec);
  }
};
}  // namespace

std::string temp_dir() {
  static TempRoot root;
  static std::atomic<int> counter{0};
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "misc";
  fs::path p = root.root / (name + "_" + std::to_string(counter++));
  fs::create_directories(p);
  return p.string();
}

}  // namespace pm::test

#include "pm/base/test_hold.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "pm/base/error.h"
#include "pm/base/log.h"

namespace pm {
namespace {
struct HoldConfig {
  std::string point;
  double seconds = 120;
};
const HoldConfig& config() {
  static const HoldConfig c = [] {
    HoldConfig h;
    if (const char* p = std::getenv("PM_TEST_HOLD")) h.point = p;
    if (const char* s = std::getenv("PM_TEST_HOLD_SECONDS")) h.seconds = std::atof(s);
    return h;
  }();
  return c;
}
}  // namespace

void test_hold_point(const std::string& point) {
  const HoldConfig& c = config();
  if (c.point.empty() || c.point != point) return;
  std::fprintf(stderr, "%s: test hold at %s\n", tool_name().c_str(), point.c_str());
  std::fflush(stderr);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(c.seconds);
  while (std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  throw Error("test hold at " + point + " was not ended by a signal within " + std::to_string(c.seconds) +
              " s (PM_TEST_HOLD_SECONDS)");
}

}  // namespace pm

#include "pm/base/stats.h"

#include <chrono>
#include <cstdio>
#include <mutex>

#include "pm/base/log.h"
#include "pm/base/test_hold.h"

namespace pm {
namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

Json& stats() {
  static Json j = Json::object();
  return j;
}

void add_seconds(const std::string& name, double s) {
  // Stages may run side by side (tighten's labels): one writer at a time.
  static std::mutex mutex;
  const std::lock_guard<std::mutex> lock(mutex);
  Json& sec = stats()["seconds"];
  if (!sec.is_object()) sec = Json::object();
  const double prev = sec.contains(name) ? sec[name].get<double>() : 0.0;
  sec[name] = prev + s;
}

ScopedStage::ScopedStage(std::string name) : name_(std::move(name)), start_(now()) {
  check_cancelled();
  test_hold_point("stage:" + name_);
}

ScopedStage::~ScopedStage() {
  const double s = now() - start_;
  add_seconds(name_, s);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3f s", s);
  debug(name_ + " " + buf);
}

}  // namespace pm

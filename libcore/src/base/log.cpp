#include "pm/base/log.h"

#include <unistd.h>

#include <cstdio>
#include <mutex>

#include "pm/base/error.h"

namespace pm {
namespace {
Verbosity g_verbosity = Verbosity::normal;
std::string g_tool = "particlemesh";
std::mutex g_mutex;
ProgressHook g_progress_hook;
CancelHook g_cancel_hook;
WarningHook g_warning_hook;

void emit(const std::string& msg) {
  std::lock_guard<std::mutex> lock(g_mutex);
  std::fprintf(stderr, "%s: %s\n", g_tool.c_str(), msg.c_str());
  std::fflush(stderr);
}
}  // namespace

void set_verbosity(Verbosity v) { g_verbosity = v; }
Verbosity verbosity() { return g_verbosity; }
void set_tool_name(const std::string& name) { g_tool = name; }
const std::string& tool_name() { return g_tool; }

void info(const std::string& msg) {
  if (g_verbosity >= Verbosity::normal) emit(msg);
}
void debug(const std::string& msg) {
  if (g_verbosity >= Verbosity::verbose) emit(msg);
}
void warn(const std::string& msg) {
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    if (g_warning_hook) g_warning_hook(msg);
  }
  if (g_verbosity >= Verbosity::normal) emit("warning: " + msg);
}

void set_progress_hook(ProgressHook hook) { g_progress_hook = std::move(hook); }
void set_cancel_hook(CancelHook hook) { g_cancel_hook = std::move(hook); }
void set_warning_hook(WarningHook hook) {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_warning_hook = std::move(hook);
}

void check_cancelled() {
  if (g_cancel_hook && g_cancel_hook()) throw Cancelled("cancelled");
}

Progress::Progress(std::string label, std::size_t total) : label_(std::move(label)), total_(total) {}

Progress::~Progress() { finish(); }

void Progress::update(std::size_t done, const std::string& detail) {
  if (g_progress_hook) g_progress_hook(label_, done, total_, detail);
  check_cancelled();
  if (g_verbosity == Verbosity::quiet || finished_) return;
  const double t = clock_.seconds();
  const bool tty = ::isatty(STDERR_FILENO);
  const double every = tty ? 0.1 : 5.0;
  if (t < 1.0 || (last_ >= 0 && t - last_ < every)) return;
  last_ = t;
  std::lock_guard<std::mutex> lock(g_mutex);
  if (tty) {
    const int width = 30;
    const double f = total_ ? std::min(1.0, double(done) / double(total_)) : 0.0;
    const int fill = int(f * width);
    std::fprintf(stderr, "\r%s: %s [%.*s%*s] %zu/%zu %s %.1fs\x1b[K", g_tool.c_str(), label_.c_str(), fill,
                 "##############################", width - fill, "", done, total_, detail.c_str(), t);
  } else {
    std::fprintf(stderr, "%s: %s %zu/%zu %s (%.1f s)\n", g_tool.c_str(), label_.c_str(), done, total_,
                 detail.c_str(), t);
  }
  std::fflush(stderr);
}

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  if (last_ >= 0 && ::isatty(STDERR_FILENO) && g_verbosity != Verbosity::quiet) {
    std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }
}

}  // namespace pm

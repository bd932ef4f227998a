#pragma once
// People-facing messages on stderr: verbosity levels, stage timers, progress.
#include <chrono>
#include <cstddef>
#include <functional>
#include <string>

namespace pm {

enum class Verbosity { quiet = 0, normal = 1, verbose = 2 };

void set_verbosity(Verbosity v);
Verbosity verbosity();
/// Name printed before messages ("particles: ...").
void set_tool_name(const std::string& name);
const std::string& tool_name();

/// A line on stderr at normal verbosity ("tool: msg").
void info(const std::string& msg);
/// A line on stderr only with -v.
void debug(const std::string& msg);
/// A warning on stderr unless -q.
void warn(const std::string& msg);

/// Front-end hooks (the Python module; tools set none). All are global, for
/// one run at a time, and called only from the thread running the long loop
/// (never from inside pm::parallel_for), so a hook may take a lock such as
/// Python's GIL.
/// Progress hook: called by every Progress::update(done, detail) with the
/// loop's label, done, total and detail, whatever the verbosity.
using ProgressHook = std::function<void(const std::string& label, std::size_t done, std::size_t total,
                                        const std::string& detail)>;
void set_progress_hook(ProgressHook hook);
/// Cancel hook: returns true when the run should stop.
using CancelHook = std::function<bool()>;
void set_cancel_hook(CancelHook hook);
/// Warning hook: when set, every pm::warn also goes to it, whatever the
/// verbosity (the Python module turns them into Python warnings). Called
/// under the log's lock, from any thread: it must not block.
using WarningHook = std::function<void(const std::string& msg)>;
void set_warning_hook(WarningHook hook);
/// Called by long loops once per iteration or stage (particle relaxation,
/// tightening flow steps, every ScopedStage): \throw Cancelled when the
/// cancel hook returns true. One empty-function test when no hook is set.
void check_cancelled();

/// Wall-clock stopwatch.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  void reset() { start_ = std::chrono::steady_clock::now(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

/// Progress of a long loop: a bar when stderr is a terminal, otherwise a plain
/// line every few seconds; nothing when quiet. Cheap to call every iteration.
/// update() also calls the progress hook (every call) and check_cancelled().
class Progress {
 public:
  Progress(std::string label, std::size_t total);
  ~Progress();
  void update(std::size_t done, const std::string& detail = {});
  void finish();

 private:
  std::string label_;
  std::size_t total_;
  Stopwatch clock_;
  double last_ = -1;
  bool finished_ = false;
};

}  // namespace pm

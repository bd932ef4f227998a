#include "pm/cli/run_tool.h"

#include <gnu/libc-version.h>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <new>
#include <thread>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/stats.h"
#include "pm/base/test_hold.h"
#include "pm/io/output_path.h"

namespace pm {

const char* version_string() { return PM_VERSION; }

namespace {
// The tool's name for the signal handler's message (no allocation there).
char g_signal_name[64] = "particlemesh";

void write_stderr(const char* s) noexcept {
  std::size_t n = 0;
  while (s[n]) ++n;
  while (n > 0) {
    const ssize_t w = ::write(2, s, n);
    if (w <= 0) return;
    s += w;
    n -= std::size_t(w);
  }
}

void on_signal(int sig) {
  // The outputs are being renamed into place: let that finish (commit_deferred
  // hands the signal back and Tool::run re-raises it).
  if (hold_signal_during_commit(sig)) return;
  remove_pending_temp_files();
  write_stderr(g_signal_name);
  write_stderr(sig == SIGINT ? ": interrupted by SIGINT" : ": interrupted by SIGTERM");
  write_stderr("; no output written, temporary files removed\n");
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

const char kHugeTunable[] = "glibc.malloc.hugetlb";

std::string thp_mode() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(f, line);
  const std::size_t a = line.find('['), b = line.find(']');
  return a != std::string::npos && b != std::string::npos && b > a ? line.substr(a + 1, b - a - 1) : "";
}

bool glibc_has_hugetlb_tunable() {
  int major = 0, minor = 0;
  return std::sscanf(gnu_get_libc_version(), "%d.%d", &major, &minor) == 2 && (major > 2 || (major == 2 && minor >= 35));
}

// Valgrind runs the program itself; it would not follow the second execution
// (--trace-children=no), and the user would lose the check without noticing.
bool under_valgrind() {
  const char* pre = std::getenv("LD_PRELOAD");
  return pre != nullptr && std::strstr(pre, "vgpreload") != nullptr;
}

// Set for the second execution only, so that nothing can make a tool execute
// itself again and again.
const char kReexecMark[] = "PM_HUGE_PAGES_REEXECUTED";

// Large buffers on transparent huge pages. The tools allocate volumes of
// tens of megabytes and touch every page once; with the kernel's default
// 4 KiB pages each first touch is a page fault, and on a virtual machine
// those faults took a quarter to a third of the pipelines' wall time (frog5
// `make materials` 18.5-20.7 -> 13.2-16.4 s, the brain `surface` 48.9-52.5
// -> 32.1-34.5 s, the same output bytes). Where the kernel gives huge pages
// only to memory that asks for them (/sys/kernel/mm/transparent_hugepage/
// enabled = madvise), glibc (>= 2.35) asks for its large blocks when the
// tunable glibc.malloc.hugetlb=1 is set. It asks only in its main arena and
// for blocks it maps on their own, not in the arenas it makes for other
// threads, which also unmap and map again whole 64 MiB heaps as they empty
// and fill: so glibc.malloc.arena_max=1 too (unless the user set it), and
// every thread allocates from the main arena (frog5's tighten 70k -> 5k page
// faults, 2.9 -> 2.5 s; the hot loops allocate nothing, so the one arena's
// lock is not contended). glibc reads tunables only at start-up: the tool sets
// them and executes itself again, once (same process id, name, arguments and
// descriptors). Not when GLIBC_TUNABLES already says anything about hugetlb
// (the user's choice), with PM_HUGE_PAGES=0, under valgrind or in a
// sanitizer build, or where it cannot help (THP always or never, an older
// glibc). Returns whether large blocks go on huge pages.
bool huge_pages_or_reexec(char** argv) {
  const bool again = std::getenv(kReexecMark) != nullptr;
  if (again) ::unsetenv(kReexecMark);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  (void)argv;
  (void)again;
  return false;  // the sanitizers' allocators ignore glibc's tunables
#else
  const std::string mode = thp_mode();
  if (mode == "always") return true;
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (tunables != nullptr) {
    if (const char* t = std::strstr(tunables, kHugeTunable)) {
      const char* eq = std::strchr(t, '=');
      return mode == "madvise" && eq != nullptr && eq[1] >= '1' && eq[1] <= '9';
    }
  }
  const char* opt = std::getenv("PM_HUGE_PAGES");
  if (again || mode != "madvise" || (opt != nullptr && std::strcmp(opt, "0") == 0) ||
      !glibc_has_hugetlb_tunable() || under_valgrind())
    return false;
  const std::string old = tunables != nullptr ? tunables : "";
  std::string value = (old.empty() ? "" : old + ":") + kHugeTunable + "=1";
  if (old.find("glibc.malloc.arena_max") == std::string::npos) value += ":glibc.malloc.arena_max=1";
  if (::setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0 || ::setenv(kReexecMark, "1", 1) != 0) return false;
  // The binary's own path, not /proc/self/exe: the process keeps its name
  // (ps, top, pkill show "tighten", not "exe").
  char self[4096];
  const ssize_t len = ::readlink("/proc/self/exe", self, sizeof self - 1);
  if (len > 0) {
    self[len] = '\0';
    ::execv(self, argv);
  }
  // Could not execute itself (no /proc): go on with small pages.
  ::unsetenv(kReexecMark);
  if (tunables != nullptr)
    ::setenv("GLIBC_TUNABLES", old.c_str(), 1);
  else
    ::unsetenv("GLIBC_TUNABLES");
  return false;
#endif
}

class HelpFormatter : public CLI::Formatter {
 public:
  explicit HelpFormatter(std::string example) : example_(std::move(example)) {}
  std::string make_footer(const CLI::App* app) const override {
    std::string f = CLI::Formatter::make_footer(app);
    return f + "\nExample:\n  " + example_ + "\n";
  }

 private:
  std::string example_;
};
}  // namespace

Tool::Tool(std::string name, std::string description, std::string example)
    : app(description, name), name_(std::move(name)) {
  app.formatter(std::make_shared<HelpFormatter>(std::move(example)));
  app.get_formatter()->column_width(34);
  app.add_flag("-v,--verbose", flags.verbose, "Print stage timings and details on stderr");
  app.add_flag("-q,--quiet", flags.quiet, "Print nothing but errors");
  app.add_option("--stats", flags.stats_path, "Write run statistics as one JSON object to FILE ('-' = stdout)");
  app.add_option("--threads", flags.threads, "Worker threads (0 = all cores)")->check(CLI::Range(0, 4096));
  app.add_option("--seed", flags.seed, "Random seed; same seed and threads give identical output")
      ->capture_default_str();
  app.set_version_flag("--version", std::string(name_) + " (particlemesh) " + PM_VERSION);
}

int Tool::run(int argc, char** argv, const std::function<void()>& body) {
  const bool huge_pages = huge_pages_or_reexec(argv);
  set_tool_name(name_);
  std::snprintf(g_signal_name, sizeof g_signal_name, "%s", name_.c_str());
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, like every other error: the message, then where to look.
    std::cerr << name_ << ": usage error: " << e.what() << " (run " << name_ << " --help for the options)\n";
    return kExitUsage;
  }
  try {
    check_output_path(flags.stats_path, OutputKind::json, "--stats");
  } catch (const UsageError& e) {
    std::cerr << name_ << ": usage error: " << e.what() << "\n";
    return kExitUsage;
  }
  set_verbosity(flags.quiet ? Verbosity::quiet : (flags.verbose ? Verbosity::verbose : Verbosity::normal));
  const int threads = flags.threads > 0 ? flags.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  tbb::global_control control(tbb::global_control::max_allowed_parallelism, std::size_t(threads));

  Json& s = stats();
  s["tool"] = name_;
  s["version"] = PM_VERSION;
  s["threads"] = threads;
  s["seed"] = flags.seed;
  s["huge_pages"] = huge_pages;
  int code = kExitOk;
  Stopwatch total;
  // Every output of the body is renamed into place together at the end, so a
  // failed or interrupted run leaves none of them (base/atomic_file.h).
  defer_commits(true);
  int late_signal = 0;
  try {
    try {
      body();
    } catch (const CheckFailed& e) {
      // A checker's report is still written: it says why the check failed.
      std::cerr << name_ << ": check failed: " << e.what() << "\n";
      code = kExitCheck;
    }
    test_hold_point("commit");
    late_signal = commit_deferred();
  } catch (const UsageError& e) {
    discard_deferred();
    std::cerr << name_ << ": usage error: " << e.what() << "\n";
    return kExitUsage;
  } catch (const std::bad_alloc&) {
    discard_deferred();
    std::cerr << name_ << ": error: out of memory\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    discard_deferred();
    std::cerr << name_ << ": error: " << e.what() << "\n";
    return kExitFailure;
  }
  defer_commits(false);
  if (late_signal != 0) {
    std::cerr << name_ << ": interrupted while its outputs were renamed into place; they are complete\n";
    std::signal(late_signal, SIG_DFL);
    std::raise(late_signal);
  }
  add_seconds("total", total.seconds());
  // Minor page faults: first touches of new memory (far fewer on huge pages).
  rusage ru{};
  if (::getrusage(RUSAGE_SELF, &ru) == 0) s["minor_page_faults"] = std::int64_t(ru.ru_minflt);
  if (!flags.stats_path.empty()) {
    const std::string text = s.dump(2) + "\n";
    if (flags.stats_path == "-") {
      std::cout << text;
      std::cout.flush();
    } else {
      try {
        write_atomically(flags.stats_path, [&](const std::string& tmp) {
          std::ofstream f(tmp);
          f << text;
          if (!f) throw IoError(quote(flags.stats_path) + ": cannot write stats");
        });
      } catch (const std::exception& e) {
        std::cerr << name_ << ": error: " << e.what() << "\n";
        return kExitFailure;
      }
    }
  }
  return code;
}

}  // namespace pm

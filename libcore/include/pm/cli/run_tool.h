#pragma once
// The shared frame of every executable: common flags, exception-to-exit-code
// mapping, stats output, signal-safe temporary files.
//
//   int main(int argc, char** argv) {
//     pm::Tool tool("volconv", "Convert volumes ...", "volconv head.nrrd head.vdb");
//     std::string in; tool.app.add_option("input", in, "...")->required();
//     return tool.run(argc, argv, [&] { ... });
//   }
#include <CLI/CLI.hpp>
#include <cstdint>
#include <functional>
#include <string>

namespace pm {

/// Exit codes: 0 ok, 1 run-time failure or bad input data, 2 usage, 3 check failed.
enum ExitCode { kExitOk = 0, kExitFailure = 1, kExitUsage = 2, kExitCheck = 3 };

const char* version_string();

struct CommonFlags {
  bool verbose = false;
  bool quiet = false;
  std::string stats_path;  ///< "" none, "-" stdout
  int threads = 0;         ///< 0 = all cores
  std::uint64_t seed = 1;
};

class Tool {
 public:
  /// name: executable name; description: one paragraph; example: shown at the
  /// end of --help.
  Tool(std::string name, std::string description, std::string example);
  CLI::App app;
  CommonFlags flags;

  /// Parse argv, set verbosity/threads, run body, write stats, map exceptions
  /// to "name: error: message" and an exit code. Returns the exit code.
  int run(int argc, char** argv, const std::function<void()>& body);

 private:
  std::string name_;
};

}  // namespace pm

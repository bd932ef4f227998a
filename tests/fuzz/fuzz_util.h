#pragma once
// Shared harness for the libFuzzer targets: the readers take paths, so each
// input is written to a file in a per-process folder on /dev/shm (tmpfs, so
// no disk I/O) and the reader is called on it. Any pm::Error is the expected
// way to reject bad input; anything else (a crash, a sanitizer report, a
// foreign exception escaping, a hang, an OOM) is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <typeinfo>

#include "pm/base/error.h"

namespace pm::fuzz {

/// Folder for this process's input files (created once, under /dev/shm when
/// it exists, else TMPDIR or /tmp).
const std::string& work_dir();

/// Write `size` bytes to work_dir()/name and return the full path.
std::string put_file(const std::string& name, const std::uint8_t* data, std::size_t size);

/// Split a two-file input (header + data file) at the first occurrence of
/// kSplit; when it is absent the whole input is the header and the data file
/// is empty.
constexpr const char* kSplit = "\n#--data--\n";
void split_input(const std::uint8_t* data, std::size_t size, std::string& header, std::string& rest);

/// Call fn(); swallow pm::Error (the readers' documented way to refuse bad
/// input) and abort on any other exception so that libFuzzer reports it.
template <class F>
void expect_pm_errors_only(F&& fn) {
  try {
    fn();
  } catch (const pm::Error&) {
    // Expected rejection of bad input.
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz: a non-pm exception escaped the reader: %s: %s\n", typeid(e).name(), e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "fuzz: an unknown exception escaped the reader\n");
    std::abort();
  }
}

}  // namespace pm::fuzz

// OpenVDB reader (.vdb, first float grid or the grid named "field").
//
// OpenVDB sizes buffers and strings from fields in the file before it can
// know the data are not there (a compressed block of 0x1000_0000_0000 bytes,
// a 4 GiB grid name). A release build gets std::bad_alloc (or a short-lived
// allocation followed by a short read), which read_vdb turns into a clean
// InputError (tests/data/regress/vdb-*); AddressSanitizer's own operator new
// aborts on such a request instead, even with allocator_may_return_null=1.
// So this target replaces operator new / new[] with versions that throw
// std::bad_alloc beyond kCap, as a process under a memory limit would.
// Every allocation still goes through ASan's malloc, so overflows, use after
// free and leaks are still found; only the new-vs-free mismatch check is off
// (libstdc++ pairs some of its own new and delete internally).
#include <cstdlib>
#include <new>

#include "fuzz_util.h"
#include "pm/io/volume_io.h"

namespace {
// 64 MiB: with a 1 GiB cap OpenVDB zero-filled strings of up to 1 GiB that
// files of a few kB declare, and the target ran at 3 executions/s.
constexpr std::size_t kCap = std::size_t(64) << 20;
}

namespace {
void* capped_alloc(std::size_t n) {
  if (n > kCap) throw std::bad_alloc();
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t n) { return capped_alloc(n); }
void* operator new[](std::size_t n) { return capped_alloc(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

extern "C" const char* __asan_default_options() { return "alloc_dealloc_mismatch=0"; }

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("fuzz.vdb", data, size);
  pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
  return 0;
}

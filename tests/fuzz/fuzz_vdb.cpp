// OpenVDB reader (.vdb, first float grid or the grid named "field").
#include "fuzz_util.h"
#include "pm/io/volume_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("fuzz.vdb", data, size);
  pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
  return 0;
}

// MetaImage reader: attached .mha (raw or zraw) and, when the input holds the
// split marker, a detached .mhd header plus its data file (fuzz.raw / fuzz.zraw).
#include "fuzz_util.h"
#include "pm/io/volume_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string header, rest;
  pm::fuzz::split_input(data, size, header, rest);
  if (header.size() == size) {
    const std::string path = pm::fuzz::put_file("fuzz.mha", data, size);
    pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
    return 0;
  }
  const auto* r = reinterpret_cast<const std::uint8_t*>(rest.data());
  pm::fuzz::put_file("fuzz.raw", r, rest.size());
  pm::fuzz::put_file("fuzz.zraw", r, rest.size());
  const std::string path =
      pm::fuzz::put_file("fuzz.mhd", reinterpret_cast<const std::uint8_t*>(header.data()), header.size());
  pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
  return 0;
}

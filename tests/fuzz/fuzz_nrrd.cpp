// NRRD reader: attached .nrrd (raw, ascii, gzip encodings) and, when the input
// holds the split marker, a detached .nhdr header plus its data file (written
// under both names the corpus headers use: fuzz.raw and fuzz.raw.gz).
#include "fuzz_util.h"
#include "pm/io/volume_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string header, rest;
  pm::fuzz::split_input(data, size, header, rest);
  if (header.size() == size) {
    const std::string path = pm::fuzz::put_file("fuzz.nrrd", data, size);
    pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
    return 0;
  }
  const auto* r = reinterpret_cast<const std::uint8_t*>(rest.data());
  pm::fuzz::put_file("fuzz.raw", r, rest.size());
  pm::fuzz::put_file("fuzz.raw.gz", r, rest.size());
  const std::string path =
      pm::fuzz::put_file("fuzz.nhdr", reinterpret_cast<const std::uint8_t*>(header.data()), header.size());
  pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
  return 0;
}

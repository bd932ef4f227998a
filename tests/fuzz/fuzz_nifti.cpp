// NIfTI-1 reader: .nii, or .nii.gz when the input starts with the gzip magic bytes.
#include "fuzz_util.h"
#include "pm/io/volume_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool gz = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
  const std::string path = pm::fuzz::put_file(gz ? "fuzz.nii.gz" : "fuzz.nii", data, size);
  pm::fuzz::expect_pm_errors_only([&] { pm::read_volume(path); });
  return 0;
}

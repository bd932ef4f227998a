// OBJ mesh reader through pm::read_mesh.
#include "fuzz_util.h"
#include "pm/io/mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("fuzz.obj", data, size);
  pm::fuzz::expect_pm_errors_only([&] { pm::read_mesh(path).validate("fuzz"); });
  return 0;
}

#include "fuzz_util.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace pm::fuzz {

const std::string& work_dir() {
  static const std::string dir = [] {
    std::string base = "/dev/shm";
    if (!std::filesystem::is_directory(base)) {
      const char* t = std::getenv("TMPDIR");
      base = t && *t ? t : "/tmp";
    }
    std::string tmpl = base + "/pm_fuzz_XXXXXX";
    if (!mkdtemp(tmpl.data())) {
      std::perror("fuzz: mkdtemp");
      std::abort();
    }
    // Remove the folder when the fuzzer exits normally.
    static const std::string keep = tmpl;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(keep, ec);
    });
    return tmpl;
  }();
  return dir;
}

std::string put_file(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::string path = work_dir() + "/" + name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) {
    std::perror(path.c_str());
    std::abort();
  }
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  return path;
}

void split_input(const std::uint8_t* data, std::size_t size, std::string& header, std::string& rest) {
  const std::string all(reinterpret_cast<const char*>(data), size);
  const std::size_t at = all.find(kSplit);
  if (at == std::string::npos) {
    header = all;
    rest.clear();
    return;
  }
  header = all.substr(0, at);
  rest = all.substr(at + std::strlen(kSplit));
}

}  // namespace pm::fuzz

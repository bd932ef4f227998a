#include "pm/io/vdb.h"

#include <dlfcn.h>

#include <filesystem>
#include <string>

#include "openvdb_plugin.h"
#include "pm/base/error.h"

namespace pm {
namespace {

[[maybe_unused]] const char* const kPluginName = "libpmcore_openvdb.so";

[[maybe_unused]] const OpenVdbPlugin* load_plugin() {
  // Beside libpmcore.so (the build tree and an installation alike), else
  // wherever the dynamic loader finds it.
  std::string beside;
  Dl_info info;
  if (dladdr(reinterpret_cast<void*>(&openvdb_plugin), &info) && info.dli_fname)
    beside = (std::filesystem::path(info.dli_fname).parent_path() / kPluginName).string();
  void* h = beside.empty() ? nullptr : dlopen(beside.c_str(), RTLD_NOW | RTLD_LOCAL);
  std::string first_error = h || beside.empty() ? "" : dlerror();
  if (!h) h = dlopen(kPluginName, RTLD_NOW | RTLD_LOCAL);
  if (!h) {
    const char* e = dlerror();
    throw Error(std::string("OpenVDB support: cannot load ") + (beside.empty() ? kPluginName : beside) + " (" +
                (first_error.empty() ? (e ? e : "unknown error") : first_error) +
                "); expected the plugin built and installed beside libpmcore.so");
  }
  auto entry = reinterpret_cast<const OpenVdbPlugin* (*)()>(dlsym(h, "pm_openvdb_plugin"));
  if (!entry) throw Error(std::string("OpenVDB support: ") + kPluginName + " has no entry point pm_openvdb_plugin");
  const OpenVdbPlugin* p = entry();
  if (!p || p->abi != kOpenVdbPluginAbi)
    throw Error(std::string("OpenVDB support: ") + kPluginName + " is from another build (interface version " +
                std::to_string(p ? p->abi : -1) + ", expected " + std::to_string(kOpenVdbPluginAbi) + ")");
  return p;
}

}  // namespace

const OpenVdbPlugin& openvdb_plugin() {
#ifdef PM_OPENVDB_LINKED  // the fuzz targets link the plugin's sources in
  return *pm_openvdb_plugin();
#else
  static const OpenVdbPlugin* const p = load_plugin();  // a throw leaves it for the next call
  return *p;
#endif
}

Volume read_vdb(const std::string& path, const std::string& grid_name) {
  return openvdb_plugin().read(path, grid_name);
}

void write_vdb(const Volume& v, const std::string& path, const std::string& grid_name) {
  openvdb_plugin().write(v, path, grid_name);
}

}  // namespace pm

#pragma once
// The functions that need OpenVDB live in a plugin, libpmcore_openvdb.so,
// beside libpmcore.so and loaded on first use: OpenVDB's shared library
// binds about 57,000 symbols when a process loads it (about 30 ms), which
// every tool paid at start-up though only VDB files, mesh distances and the
// marching-cubes baseline need it. libpmcore's read_vdb, write_vdb,
// mesh_to_sdf and marching_cubes_baseline call through this table.
#include <string>

#include "pm/base/mesh.h"
#include "pm/base/volume.h"
#include "pm/field/mesh_sdf.h"

namespace pm {

/// Bumped whenever the table or a signature changes.
constexpr int kOpenVdbPluginAbi = 2;

struct OpenVdbPlugin {
  int abi = kOpenVdbPluginAbi;
  Volume (*read)(const std::string& path, const std::string& grid_name) = nullptr;
  void (*write)(const Volume& v, const std::string& path, const std::string& grid_name) = nullptr;
  /// On `grid`, mesh_sdf_grid(m, p) (which has checked m and p).
  Volume (*mesh_to_sdf)(const Mesh& m, const MeshSdfParams& p, const MeshSdfGrid& grid) = nullptr;
  /// The triangles (quads split along the shorter diagonal) of the level
  /// g = iso of the volume, g = F or -F (material below or above iso).
  Mesh (*marching_cubes)(const Volume& v, double iso, bool material_below) = nullptr;
};

/// The plugin's table, loaded once (thread-safe).
/// \throw Error naming the library and the loader's message when it cannot be loaded.
const OpenVdbPlugin& openvdb_plugin();

// Defined in the plugin.
Volume openvdb_read(const std::string& path, const std::string& grid_name);
void openvdb_write(const Volume& v, const std::string& path, const std::string& grid_name);
Volume openvdb_mesh_to_sdf(const Mesh& m, const MeshSdfParams& p, const MeshSdfGrid& grid);
Mesh openvdb_marching_cubes(const Volume& v, double iso, bool material_below);
/// openvdb::initialize(), once (thread-safe).
void ensure_openvdb_initialized();

}  // namespace pm

/// The plugin's entry point (looked up by name with dlsym).
extern "C" const pm::OpenVdbPlugin* pm_openvdb_plugin();

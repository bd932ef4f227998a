#include "pm/io/output_path.h"

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/mesh.h"
#include "pm/io/poly_mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/io/volume_io.h"

namespace pm {
namespace {

const char* kind_name(OutputKind k) {
  switch (k) {
    case OutputKind::volume: return "volume";
    case OutputKind::mesh: return "mesh";
    case OutputKind::points: return "point set";
    case OutputKind::tet_mesh: return "tetrahedral mesh";
    case OutputKind::poly_mesh: return "polygon mesh";
    case OutputKind::png: return "image";
    case OutputKind::json: return "JSON";
  }
  return "output";
}

bool known(const std::string& path, OutputKind k) {
  switch (k) {
    case OutputKind::volume: return is_volume_path(path);
    case OutputKind::mesh: return is_mesh_path(path);
    case OutputKind::points: return is_mesh_path(path, true);
    case OutputKind::tet_mesh: return is_tet_mesh_path(path);
    case OutputKind::poly_mesh: return is_poly_mesh_path(path);
    case OutputKind::png: return file_extension(path) == ".png";
    case OutputKind::json: return path == "-" || file_extension(path) == ".json";
  }
  return false;
}

}  // namespace

std::string output_extensions(OutputKind kind) {
  switch (kind) {
    case OutputKind::volume: return volume_extensions();
    case OutputKind::mesh: return mesh_extensions();
    case OutputKind::points: return mesh_extensions(true);
    case OutputKind::tet_mesh: return tet_mesh_extensions();
    case OutputKind::poly_mesh: return poly_mesh_extensions();
    case OutputKind::png: return ".png";
    case OutputKind::json: return ".json (or - for stdout)";
  }
  return "";
}

void check_output_path(const std::string& path, OutputKind kind, const std::string& option) {
  if (path.empty() || known(path, kind)) return;
  const std::string e = file_extension(path);
  throw UsageError(option + " " + quote(path) + ": unknown " + kind_name(kind) + " extension " +
                   (e.empty() ? std::string("(none)") : quote(e)) + "; expected one of " + output_extensions(kind));
}

}  // namespace pm

// The table of tetrahedral mesh formats, write_tet_mesh and read_tet_mesh (see pm/io/tet_mesh.h).
#include "pm/io/tet_mesh.h"

#include <fstream>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/gmsh.h"
#include "pm/io/medit.h"
#include "pm/io/vtk.h"
#include "pm/io/vtu.h"

namespace pm {
namespace {

using Writer = void (*)(const LabelledTets& t, const std::string& path, const TetWriteParams& p);
/// May return no tetrahedra (except MEDIT's, which throws then).
using Reader = LabelledTets (*)(const std::string& path, WorldFrame* frame);

struct TetFormat {
  const char* ext;
  Writer write;
  Reader read;
  bool only_tets;  ///< read_tet_mesh is the only reader of the extension (no surface reader)
};

const std::vector<TetFormat>& formats() {
  static const std::vector<TetFormat> kFormats = {
      {".mesh",
       [](const LabelledTets& t, const std::string& f, const TetWriteParams& p) { write_medit_tets(t, f, p.frame); },
       read_medit_tets, false},
      {".vtu", [](const LabelledTets& t, const std::string& f, const TetWriteParams& p) { write_vtu(t, f, p.frame); },
       read_vtu, true},
      {".vtk",
       [](const LabelledTets& t, const std::string& f, const TetWriteParams& p) {
         write_vtk_tets(t, f, p.binary, p.frame);
       },
       read_vtk_tets, false},
      {".msh", [](const LabelledTets& t, const std::string& f, const TetWriteParams& p) { write_gmsh(t, f, p.frame); },
       read_gmsh, true},
  };
  return kFormats;
}

const TetFormat* find(const std::string& path) {
  const std::string ext = file_extension(path);
  for (const auto& f : formats())
    if (ext == f.ext) return &f;
  return nullptr;
}

}  // namespace

void LabelledTets::validate(const std::string& what) const {
  const std::size_t nv = vertices.size();
  if (materials.size() != tets.size())
    throw InputError(what + ": " + std::to_string(materials.size()) + " materials for " + std::to_string(tets.size()) +
                     " tetrahedra; expected one each");
  if (triangle_labels.size() != triangles.size())
    throw InputError(what + ": " + std::to_string(triangle_labels.size()) + " label pairs for " +
                     std::to_string(triangles.size()) + " triangles; expected one each");
  auto check = [&](const char* kind, std::size_t i, int v) {
    if (v < 0 || std::size_t(v) >= nv)
      throw InputError(what + ": " + kind + " " + std::to_string(i) + " refers to vertex " + std::to_string(v) +
                       "; expected an index in [0, " + std::to_string(nv) + ")");
  };
  for (std::size_t i = 0; i < tets.size(); ++i)
    for (int v : tets[i]) check("tetrahedron", i, v);
  for (std::size_t i = 0; i < triangles.size(); ++i)
    for (int v : triangles[i]) check("triangle", i, v);
}

std::string tet_mesh_extensions() {
  std::string s;
  for (const auto& f : formats()) s += (s.empty() ? "" : " ") + std::string(f.ext);
  return s;
}

bool is_tet_mesh_path(const std::string& path) { return find(path) != nullptr; }

LabelledTets read_tet_mesh(const std::string& path) {
  const TetFormat* f = find(path);
  if (!f) {
    const std::string e = file_extension(path);
    throw UsageError("read_tet_mesh: " + quote(path) + ": unknown tetrahedral mesh extension " +
                     (e.empty() ? std::string("(none)") : quote(e)) + "; expected one of " + tet_mesh_extensions());
  }
  WorldFrame frame = WorldFrame::lps;
  LabelledTets t = f->read(path, &frame);
  if (t.tets.empty())
    throw InputError("read_tet_mesh: " + quote(path) + ": no tetrahedra (" + std::to_string(t.triangles.size()) +
                     " triangles); expected a tetrahedral mesh");
  if (frame != WorldFrame::lps)
    for (Vec3& v : t.vertices) v = Vec3(-v.x, -v.y, v.z);
  return t;
}

bool file_has_tetrahedra(const std::string& path) {
  const TetFormat* f = find(path);
  if (!f) return false;
  if (std::string(f->ext) == ".mesh") return medit_has_tetrahedra(path);
  try {
    return !f->read(path, nullptr).tets.empty();
  } catch (const InputError&) {
    return false;
  } catch (const IoError&) {
    return false;
  }
}

bool is_tet_mesh_file(const std::string& path) {
  const TetFormat* f = find(path);
  if (!f) return false;
  if (f->only_tets) return true;
  if (std::string(f->ext) == ".mesh") return medit_has_tetrahedra(path);
  try {
    return !f->read(path, nullptr).tets.empty();
  } catch (const IoError&) {
    return false;  // the surface reader says why
  } catch (const InputError&) {
    // A legacy UNSTRUCTURED_GRID that the surface reader cannot read either
    // (a truncated or damaged tetrahedral file, say) goes to the tetrahedral
    // reader, whose message names the line; other datasets stay surfaces.
    std::ifstream in(path, std::ios::binary);
    std::string head(256, '\0');
    in.read(&head[0], std::streamsize(head.size()));
    head.resize(std::size_t(in.gcount()));
    if (head.find("DATASET UNSTRUCTURED_GRID") == std::string::npos) return false;
    try {
      read_vtk(path);
      return false;
    } catch (const Error&) {
      return true;
    }
  }
}

void write_tet_mesh(const LabelledTets& t, const std::string& path, const TetWriteParams& p) {
  const TetFormat* f = find(path);
  if (!f) {
    const std::string e = file_extension(path);
    throw UsageError("write_tet_mesh: " + quote(path) + ": unknown tetrahedral mesh extension " +
                     (e.empty() ? std::string("(none)") : quote(e)) + "; expected one of " + tet_mesh_extensions());
  }
  t.validate("write_tet_mesh: " + quote(path));
  LabelledTets framed;
  const LabelledTets* out = &t;
  if (p.frame != WorldFrame::lps) {
    framed = t;
    for (Vec3& v : framed.vertices) v = Vec3(-v.x, -v.y, v.z);
    out = &framed;
  }
  write_atomically(path, [&](const std::string& tmp) { f->write(*out, tmp, p); });
}

}  // namespace pm

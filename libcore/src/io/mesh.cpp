// The table of mesh formats and the dispatch by extension. Each format lives
// in its own file (ply, vtk, medit, mesh_cgal); none of them calls back here.
#include "pm/io/mesh.h"

#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/medit.h"
#include "pm/io/mesh_cgal.h"
#include "pm/io/ply.h"
#include "pm/io/vtk.h"

namespace pm {
namespace {

using Reader = Mesh (*)(const std::string& path, WorldFrame* frame);
using Writer = void (*)(const Mesh& m, const std::string& path, const MeshWriteParams& p);

struct MeshFormat {
  const char* ext;
  bool keeps_point_sets;  // a point set with its vertex scalars survives
  bool checks_names;      // property names must be single words (PLY rules)
  Reader read;            // nullptr: written, not read
  Writer write;
};

Mesh read_ply_plain(const std::string& p, WorldFrame* f) { return read_ply(p, f); }
// Geometry-only readers state no frame: their coordinates are taken as LPS.
Mesh read_off_lps(const std::string& p, WorldFrame*) { return read_off(p); }
Mesh read_obj_lps(const std::string& p, WorldFrame*) { return read_obj(p); }
Mesh read_stl_lps(const std::string& p, WorldFrame*) { return read_stl(p); }

const std::vector<MeshFormat>& formats() {
  static const std::vector<MeshFormat> kFormats = {
      {".ply", true, true, read_ply_plain,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_ply(m, t, p.binary, p.frame); }},
      {".vtp", true, true, nullptr,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_vtp(m, t, p.frame); }},
      {".vtk", true, true, read_vtk,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_vtk(m, t, p.binary, p.frame); }},
      {".mesh", false, false, read_medit,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_medit(m, t, p.frame); }},
      {".obj", false, false, read_obj_lps,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_obj(m, t, p.frame); }},
      {".off", false, false, read_off_lps,
       [](const Mesh& m, const std::string& t, const MeshWriteParams&) { write_off(m, t); }},
      {".stl", false, false, read_stl_lps,
       [](const Mesh& m, const std::string& t, const MeshWriteParams& p) { write_stl(m, t, p.binary); }},
  };
  return kFormats;
}

const MeshFormat* find(const std::string& path) {
  const std::string ext = file_extension(path);
  for (const auto& f : formats())
    if (ext == f.ext) return &f;
  return nullptr;
}

std::string extensions(bool readable, bool points) {
  std::string s;
  for (const auto& f : formats())
    if ((!readable || f.read) && (!points || f.keeps_point_sets)) s += (s.empty() ? "" : " ") + std::string(f.ext);
  return s;
}

std::string shown(const std::string& path) {
  const std::string e = file_extension(path);
  return e.empty() ? std::string("(none)") : quote(e);
}

}  // namespace

bool is_mesh_path(const std::string& path, bool points) {
  const MeshFormat* f = find(path);
  return f && (!points || f->keeps_point_sets);
}

std::string mesh_extensions(bool points) { return extensions(false, points); }

Mesh read_mesh(const std::string& path) {
  const MeshFormat* f = find(path);
  if (!f || !f->read)
    throw UsageError("read_mesh: " + quote(path) + ": " + (f ? "meshes are written, not read, as " : "unknown mesh extension ") +
                     shown(path) + "; expected one of " + extensions(true, false));
  require_readable(path);
  WorldFrame frame = WorldFrame::lps;
  Mesh m = f->read(path, &frame);
  m.validate("read_mesh: " + quote(path));
  convert_frame(m, frame, WorldFrame::lps);
  return m;
}

void write_mesh(const Mesh& m, const std::string& path, const MeshWriteParams& p) {
  const MeshFormat* f = find(path);
  if (!f)
    throw UsageError("write_mesh: " + quote(path) + ": unknown mesh extension " + shown(path) + "; expected one of " +
                     extensions(false, false));
  const std::string where = "write_mesh: " + quote(path);
  m.validate(where);
  if (f->checks_names) check_ply_names(m, where);
  Mesh framed;
  const Mesh* out = &m;
  if (p.frame != WorldFrame::lps) {
    framed = m;
    convert_frame(framed, WorldFrame::lps, p.frame);
    out = &framed;
  }
  write_atomically(path, [&](const std::string& tmp) { f->write(*out, tmp, p); });
}

}  // namespace pm

// Writes the fuzzers' seed corpus with the project's own writers:
//   fuzz_make_corpus OUTDIR   -> OUTDIR/<target>/<name>
// Every file is tiny (a 3x2x2 volume, a tetrahedron) so that the fuzzers
// start from valid inputs of each variant: NRRD raw/gzip/ascii-free attached
// and detached, MHA raw/zraw, MHD + data, NIfTI .nii/.nii.gz, INR .inr/.inr.gz,
// VDB, PLY ASCII/binary with normals, scalars and face properties, OFF, OBJ,
// STL ASCII/binary, PLY seed points, a positive NRRD sizing field.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>

#include "../unit/nektar_fixtures.h"
#include "fuzz_util.h"
#include "pm/io/inr.h"
#include "pm/io/mesh.h"
#include "pm/io/mesh_cgal.h"
#include "pm/io/ply.h"
#include "pm/io/metaimage.h"
#include "pm/io/nifti.h"
#include "pm/io/nrrd.h"
#include "pm/io/vdb.h"

namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void spit(const fs::path& p, const std::string& s) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << s;
}

pm::Volume small_volume(pm::VoxelType t, double base) {
  pm::Geometry g = pm::Geometry::with_spacing(0.5, 0.75, 2.0, {1, -2, 3});
  pm::Volume v(t, pm::Dims{3, 2, 2}, g);
  for (std::size_t k = 0; k < v.count(); ++k) v.set(k, base + double(k % 5));
  return v;
}

pm::Mesh tetrahedron(bool extras) {
  pm::Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  if (extras) {
    pm::compute_vertex_normals(m);
    m.vertex_scalars["energy"] = {0.5, 1, 1.5, 2};
    m.face_ints["label"] = {1, 1, 2, 2};
  }
  return m;
}


// Nektar++ meshes and fields (the generators of the unit tests).
void write_nektar_seeds(const fs::path& out) {
  namespace t = pm::test;
  t::GenMesh tets, hexes;
  int v[5];
  const pm::Vec3 p[5] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  for (int k = 0; k < 5; ++k) v[k] = tets.vertex(p[k]);
  tets.add_tet({v[0], v[1], v[2], v[3]});
  tets.add_tet({v[1], v[2], v[3], v[4]});
  int w[3][2][2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) w[i][j][k] = hexes.vertex({double(i), double(j), double(k)});
  hexes.add_hex({w[0][0][0], w[1][0][0], w[1][1][0], w[0][1][0], w[0][0][1], w[1][0][1], w[1][1][1], w[0][1][1]});
  hexes.add_hex({w[1][0][0], w[2][0][0], w[2][1][0], w[1][1][0], w[1][0][1], w[2][0][1], w[2][1][1], w[1][1][1]});
  spit(out / "nektar_mesh" / "tets_plain.xml", t::mesh_xml(tets, false));
  spit(out / "nektar_mesh" / "tets_b64z.xml", t::mesh_xml(tets, true));
  spit(out / "nektar_mesh" / "hexes_plain.xml", t::mesh_xml(hexes, false));
  spit(out / "nektar_mesh" / "hexes_b64z.xml", t::mesh_xml(hexes, true));
  hexes.curved = "    <CURVED>\n      <E ID=\"0\" EDGEID=\"3\" TYPE=\"PolyEvenlySpaced\" NUMPOINTS=\"3\"> 0 0 0  0.5 0.1 0  1 0 0 </E>\n    </CURVED>\n";
  spit(out / "nektar_mesh" / "hexes_curved.xml", t::mesh_xml(hexes, false));
  t::GenBlock hex;
  hex.ids = "0-1";
  for (int k = 0; k < 128; ++k) hex.coeffs.push_back(0.1 * (k % 7) - 0.2);
  spit(out / "nektar_field" / "hexes.fld", t::field_xml({hex}));
  t::GenBlock mix;
  mix.ids = "1,0";
  mix.modes = "MIXORDER:2,2,2,3,3,3";
  for (int k = 0; k < 8 + 27; ++k) mix.coeffs.push_back(0.05 * k);
  spit(out / "nektar_field" / "hexes_mixorder.fld", t::field_xml({mix}));
  t::GenBlock a, b;
  for (t::GenBlock* blk : {&a, &b}) {
    blk->shape = "Tetrahedron";
    blk->basis = "Modified_A,Modified_B,Modified_C";
    blk->modes = "UNIORDER:3,3,3";
    blk->fields = "u,p";
    for (int k = 0; k < 20; ++k) blk->coeffs.push_back(0.3 - 0.07 * k);
  }
  a.ids = "1";
  b.ids = "0";
  b.compressed_attr = false;
  spit(out / "nektar_field" / "tets_two_blocks.fld", t::field_xml({a, b}));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: fuzz_make_corpus OUTDIR\n";
    return 2;
  }
  const fs::path out = argv[1];
  const fs::path tmp = pm::fuzz::work_dir();
  const std::string split = pm::fuzz::kSplit;
  try {
    const pm::Volume f32 = small_volume(pm::VoxelType::f32, -1.5);
    const pm::Volume u8 = small_volume(pm::VoxelType::u8, 0);
    const pm::Volume i16 = small_volume(pm::VoxelType::i16, -3);
    // NRRD attached, raw and gzip, and detached pairs (header + split + data).
    for (const auto& [name, v] : {std::pair{"f32", &f32}, std::pair{"u8", &u8}, std::pair{"i16", &i16}}) {
      for (bool gz : {false, true}) {
        const std::string stem = std::string(name) + (gz ? "_gz" : "_raw");
        pm::write_nrrd(*v, (tmp / "a.nrrd").string(), gz);
        spit(out / "nrrd" / (stem + ".nrrd"), slurp(tmp / "a.nrrd"));
        const std::string data_name = gz ? "fuzz.raw.gz" : "fuzz.raw";
        pm::write_nrrd_detached(*v, (tmp / "a.nhdr").string(), (tmp / data_name).string(), data_name, gz);
        spit(out / "nrrd" / (stem + "_detached"), slurp(tmp / "a.nhdr") + split + slurp(tmp / data_name));
        // MetaImage attached and detached.
        pm::write_metaimage(*v, (tmp / "a.mha").string(), gz);
        spit(out / "metaimage" / (stem + ".mha"), slurp(tmp / "a.mha"));
        const std::string mdata = gz ? "fuzz.zraw" : "fuzz.raw";
        pm::write_metaimage_detached(*v, (tmp / "a.mhd").string(), (tmp / mdata).string(), mdata, gz);
        spit(out / "metaimage" / (stem + "_detached"), slurp(tmp / "a.mhd") + split + slurp(tmp / mdata));
        // NIfTI and INR, plain and gzip (chosen by the extension).
        const std::string nii = gz ? "a.nii.gz" : "a.nii";
        pm::write_nifti(*v, (tmp / nii).string());
        spit(out / "nifti" / (stem + ".nii"), slurp(tmp / nii));
        const std::string inr = gz ? "a.inr.gz" : "a.inr";
        pm::write_inr(*v, (tmp / inr).string());
        spit(out / "inr" / (stem + ".inr"), slurp(tmp / inr));
      }
    }
    pm::write_vdb(f32, (tmp / "a.vdb").string());
    spit(out / "vdb" / "f32.vdb", slurp(tmp / "a.vdb"));
    // Sizing field: positive h.
    pm::Volume h = small_volume(pm::VoxelType::f32, 0.25);
    pm::write_nrrd(h, (tmp / "h.nrrd").string(), false);
    spit(out / "sizing" / "h_raw.nrrd", slurp(tmp / "h.nrrd"));
    pm::write_nrrd(h, (tmp / "h.nrrd").string(), true);
    spit(out / "sizing" / "h_gz.nrrd", slurp(tmp / "h.nrrd"));
    // Meshes.
    const pm::Mesh plain = tetrahedron(false), rich = tetrahedron(true);
    pm::write_ply(rich, (tmp / "a.ply").string(), true);
    spit(out / "ply" / "tet_binary.ply", slurp(tmp / "a.ply"));
    pm::write_ply(rich, (tmp / "a.ply").string(), false);
    spit(out / "ply" / "tet_ascii.ply", slurp(tmp / "a.ply"));
    pm::write_off(plain, (tmp / "a.off").string());
    spit(out / "off" / "tet.off", slurp(tmp / "a.off"));
    pm::write_obj(plain, (tmp / "a.obj").string());
    spit(out / "obj" / "tet.obj", slurp(tmp / "a.obj"));
    for (bool bin : {false, true}) {
      pm::write_stl(plain, (tmp / "a.stl").string(), bin);
      spit(out / "stl" / (bin ? "tet_binary.stl" : "tet_ascii.stl"), slurp(tmp / "a.stl"));
    }
    // Seeds: points near the unit sphere, with and without normals.
    pm::Mesh seeds;
    seeds.vertices = {{1, 0, 0}, {0, 1.1, 0}, {0, 0, -0.9}};
    pm::write_ply(seeds, (tmp / "s.ply").string(), false);
    spit(out / "seeds" / "three_ascii.ply", slurp(tmp / "s.ply"));
    seeds.normals = seeds.vertices;
    pm::write_ply(seeds, (tmp / "s.ply").string(), true);
    spit(out / "seeds" / "three_binary.ply", slurp(tmp / "s.ply"));
    write_nektar_seeds(out);
  } catch (const std::exception& e) {
    std::cerr << "fuzz_make_corpus: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

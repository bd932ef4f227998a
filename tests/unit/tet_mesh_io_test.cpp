// Reading labelled tetrahedral meshes (pm/io/tet_mesh.h and the format
// readers): round trips through our writers, the variants other tools write
// (built here byte by byte: VTU binary, zlib and appended, legacy 5.1, Gmsh
// 2.2 and 4.1 binary), frames, clear errors, and truncated or corrupted files
// that must fail cleanly.
#include <gtest/gtest.h>

#include <cctype>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include "pm/base/error.h"
#include "pm/io/gmsh.h"
#include "pm/io/gzip.h"
#include "pm/io/medit.h"
#include "pm/io/mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/io/vtk.h"
#include "pm/io/vtu.h"
#include "test_util.h"
#include "tet_fixtures.h"

namespace pm {
namespace {

// 2 x 2 x 1 cubes, materials 3 (the first column of cubes) and 7; coordinates
// that are not short decimals, so bit-exact round trips mean something.
LabelledTets sample() {
  const Vec3 origin(10.1, -20.3, 30.7);  // tet_box passes centroids with the origin in
  LabelledTets t = test::tet_box(2, 2, 1, 1.0, [&](const Vec3& c) { return c.x < origin.x + 1 ? 3 : 7; }, origin);
  for (std::size_t i = 0; i < t.vertices.size(); ++i) t.vertices[i] += Vec3(1e-9 * double(i), 1.0 / 3, -1.0 / 7);
  return t;
}

std::string slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
void spit(const std::string& p, const std::string& d) {
  std::ofstream(p, std::ios::binary).write(d.data(), std::streamsize(d.size()));
}
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// gtest without gmock: a substring check that prints the whole message when it fails.
::testing::AssertionResult has(const std::string& s, const std::string& sub) {
  if (s.find(sub) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "\"" << s << "\" does not contain \"" << sub << "\"";
}

void expect_same_tets(const LabelledTets& a, const LabelledTets& b, bool triangles) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(a.vertices[i][c], b.vertices[i][c]) << "vertex " << i;  // bit-exact
  EXPECT_EQ(a.tets, b.tets);
  EXPECT_EQ(a.materials, b.materials);
  if (triangles) {
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_EQ(a.triangle_labels, b.triangle_labels);
  }
}

class RoundTrip : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

TEST_P(RoundTrip, OurWriterThenReaderIsBitExact) {
  const auto [ext, binary] = GetParam();
  const LabelledTets t = sample();
  for (WorldFrame frame : {WorldFrame::lps, WorldFrame::ras}) {
    const std::string path = test::temp_dir() + "/v" + ext;
    TetWriteParams p;
    p.frame = frame;
    p.binary = binary;
    write_tet_mesh(t, path, p);
    EXPECT_TRUE(file_has_tetrahedra(path));
    EXPECT_TRUE(is_tet_mesh_file(path));
    const LabelledTets r = read_tet_mesh(path);  // back in LPS: x and y negated twice, exactly
    // Gmsh groups tetrahedra by material and triangles by label pair: the
    // order within a group is kept.
    if (ext == ".msh") {
      LabelledTets sorted = t;
      std::vector<std::size_t> order(t.tets.size());
      for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
      std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return t.materials[a] < t.materials[b]; });
      for (std::size_t i = 0; i < order.size(); ++i) {
        sorted.tets[i] = t.tets[order[i]];
        sorted.materials[i] = t.materials[order[i]];
      }
      std::vector<std::size_t> tri(t.triangles.size());
      for (std::size_t i = 0; i < tri.size(); ++i) tri[i] = i;
      std::stable_sort(tri.begin(), tri.end(),
                       [&](std::size_t a, std::size_t b) { return t.triangle_labels[a] < t.triangle_labels[b]; });
      for (std::size_t i = 0; i < tri.size(); ++i) {
        sorted.triangles[i] = t.triangles[tri[i]];
        sorted.triangle_labels[i] = t.triangle_labels[tri[i]];
      }
      expect_same_tets(sorted, r, true);
    } else {
      expect_same_tets(t, r, ext == ".mesh");
    }
    if (ext == ".vtu" || ext == ".vtk") EXPECT_TRUE(r.triangles.empty());  // our VTK writers store tetrahedra only
  }
  // The fixture has boundary (0, 3), (0, 7) and interface (3, 7) triangles.
  std::set<std::array<int, 2>> pairs(t.triangle_labels.begin(), t.triangle_labels.end());
  EXPECT_EQ(pairs, (std::set<std::array<int, 2>>{{0, 3}, {0, 7}, {3, 7}}));
}

INSTANTIATE_TEST_SUITE_P(TetFormats, RoundTrip,
                         ::testing::Values(std::make_tuple(std::string(".mesh"), false),
                                           std::make_tuple(std::string(".vtu"), false),
                                           std::make_tuple(std::string(".vtk"), false),
                                           std::make_tuple(std::string(".vtk"), true),
                                           std::make_tuple(std::string(".msh"), false)));

TEST(TetMeshRead, GmshLabelsThatAreNotPositiveComeBackFromTheNames) {
  LabelledTets t = test::tet_box(2, 1, 1, 0.5, [](const Vec3& c) { return c.x < 0.5 ? -2 : 0; });
  const std::string path = test::temp_dir() + "/neg.msh";
  write_tet_mesh(t, path);
  const LabelledTets r = read_tet_mesh(path);
  std::map<int, int> count;
  for (int m : r.materials) ++count[m];
  EXPECT_EQ(count, (std::map<int, int>{{-2, 6}, {0, 6}}));
  // Label pairs too, negative ones included. tet_box puts 0 first on the
  // boundary, (0, -2) and (0, 0), and writes (-2, 0) at the interface: three
  // groups; the reader gives the smaller label first, so (0, -2) reads (-2, 0).
  std::map<std::array<int, 2>, int> want, got;
  for (const auto& p : t.triangle_labels) ++want[{std::min(p[0], p[1]), std::max(p[0], p[1])}];
  for (const auto& p : r.triangle_labels) ++got[p];
  EXPECT_EQ(want.size(), 2u);
  EXPECT_EQ(got, want);
  EXPECT_NE(slurp(path).find("\"interface_0_-2\""), std::string::npos);
  EXPECT_EQ(r.triangles.size(), t.triangles.size());
}

TEST(TetMeshRead, SurfacesAreNotTetrahedra) {
  const std::string dir = test::temp_dir();
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  write_mesh(m, dir + "/s.vtk");
  write_mesh(m, dir + "/s.mesh");
  for (const char* f : {"/s.vtk", "/s.mesh"}) {
    EXPECT_FALSE(file_has_tetrahedra(dir + f)) << f;
    EXPECT_FALSE(is_tet_mesh_file(dir + f)) << f;
    std::string e = error_of([&] { read_tet_mesh(dir + f); });
    for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    EXPECT_TRUE(has(e, "no tetrahedra")) << f;
  }
  // A truncated tetrahedral .vtk goes to the tetrahedral reader; a truncated POLYDATA stays a surface.
  write_tet_mesh(sample(), dir + "/t.vtk");
  const std::string whole = slurp(dir + "/t.vtk");
  spit(dir + "/cut.vtk", whole.substr(0, whole.size() / 2));
  EXPECT_FALSE(file_has_tetrahedra(dir + "/cut.vtk"));
  EXPECT_TRUE(is_tet_mesh_file(dir + "/cut.vtk"));
  EXPECT_TRUE(has(error_of([&] { read_tet_mesh(dir + "/cut.vtk"); }), "(truncated"));
  spit(dir + "/cut_poly.vtk", "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 9 float\n0 0");
  EXPECT_FALSE(is_tet_mesh_file(dir + "/cut_poly.vtk"));
  EXPECT_FALSE(file_has_tetrahedra(dir + "/nope.vtu"));
  EXPECT_TRUE(is_tet_mesh_file(dir + "/nope.vtu"));  // read_tet_mesh then says why
  EXPECT_THROW(read_tet_mesh(dir + "/nope.vtu"), IoError);
  EXPECT_THROW(read_tet_mesh(dir + "/x.ply"), UsageError);
  EXPECT_FALSE(is_tet_mesh_file(dir + "/x.ply"));
}

// ---- files as other tools write them ----

// The 2 tetrahedra meshio's tests use: 5 points, materials 1 and 2, and one triangle (material 3).
const char* kPoints = "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1";

void expect_two_tets(const LabelledTets& r, bool triangle = true) {
  ASSERT_EQ(r.vertices.size(), 5u);
  EXPECT_EQ(r.vertices[4], Vec3(1, 1, 1));
  EXPECT_EQ(r.tets, (std::vector<std::array<int, 4>>{{0, 1, 2, 3}, {1, 2, 3, 4}}));
  EXPECT_EQ(r.materials, (std::vector<int>{1, 2}));
  if (triangle) {
    EXPECT_EQ(r.triangles, (std::vector<std::array<int, 3>>{{0, 1, 2}}));
    EXPECT_EQ(r.triangle_labels, (std::vector<std::array<int, 2>>{{0, 3}}));
  }
}

std::string base64(const std::string& b) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string o;
  for (std::size_t i = 0; i < b.size(); i += 3) {
    std::uint32_t w = std::uint32_t(static_cast<unsigned char>(b[i])) << 16;
    if (i + 1 < b.size()) w |= std::uint32_t(static_cast<unsigned char>(b[i + 1])) << 8;
    if (i + 2 < b.size()) w |= std::uint32_t(static_cast<unsigned char>(b[i + 2]));
    o += k[(w >> 18) & 63];
    o += k[(w >> 12) & 63];
    o += i + 1 < b.size() ? k[(w >> 6) & 63] : '=';
    o += i + 2 < b.size() ? k[w & 63] : '=';
  }
  return o;
}
template <class T>
std::string raw(const std::vector<T>& v, bool big = false) {
  std::string s(v.size() * sizeof(T), '\0');
  std::memcpy(&s[0], v.data(), s.size());
  if (big)
    for (std::size_t i = 0; i < v.size(); ++i) std::reverse(s.begin() + long(i * sizeof(T)), s.begin() + long((i + 1) * sizeof(T)));
  return s;
}
template <class H>
std::string with_header(const std::string& d, bool big) {
  return raw(std::vector<H>{H(d.size())}, big) + d;
}
// vtkZLibDataCompressor: one block; header [1, size, size, compressed size].
template <class H>
std::string zlib_block(const std::string& d) {
  const auto z = deflate_buffer(d.data(), d.size());
  return raw(std::vector<H>{1, H(d.size()), H(d.size()), H(z.size())}) + std::string(z.begin(), z.end());
}

struct VtuArray {
  std::string type, name;
  int comps;
  std::string bytes;  // the values, host (little-endian) order
};
std::vector<VtuArray> vtu_arrays(bool big) {
  return {{"Float64", "Points", 3, raw(std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}, big)},
          {"Int64", "connectivity", 1, raw(std::vector<std::int64_t>{0, 1, 2, 3, 1, 2, 3, 4, 0, 1, 2}, big)},
          {"Int32", "offsets", 1, raw(std::vector<std::int32_t>{4, 8, 11}, big)},
          {"UInt8", "types", 1, raw(std::vector<std::uint8_t>{10, 10, 5}, big)},
          {"Int16", "medit:ref", 1, raw(std::vector<std::int16_t>{1, 2, 3}, big)}};
}
// mode: "binary" (base64 inline), "zlib" (meshio's default), "raw" or
// "base64" (appended, as ParaView writes), "big" (binary, BigEndian, UInt64 header).
std::string vtu_file(const std::string& mode) {
  const bool big = mode == "big";
  const auto arrays = vtu_arrays(big);
  std::string appended;
  auto array = [&](const VtuArray& a) {
    std::string s = "<DataArray type=\"" + a.type + "\" Name=\"" + a.name + "\" NumberOfComponents=\"" +
                    std::to_string(a.comps) + "\" ";
    if (mode == "raw" || mode == "base64") {
      s += "format=\"appended\" offset=\"" + std::to_string(appended.size()) + "\"/>\n";
      const std::string block = with_header<std::uint32_t>(a.bytes, false);
      appended += mode == "raw" ? block : base64(block);
      return s;
    }
    std::string block = mode == "zlib" ? zlib_block<std::uint32_t>(a.bytes)
                        : big          ? with_header<std::uint64_t>(a.bytes, true)
                                       : with_header<std::uint32_t>(a.bytes, false);
    // meshio and VTK encode a compressed array's header and data separately.
    std::string text = mode == "zlib" ? base64(block.substr(0, 16)) + base64(block.substr(16)) : base64(block);
    return s + "format=\"binary\">\n" + text + "\n</DataArray>\n";
  };
  std::string x = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"" +
                  std::string(big ? "BigEndian" : "LittleEndian") + "\"" + (big ? " header_type=\"UInt64\"" : "") +
                  (mode == "zlib" ? " compressor=\"vtkZLibDataCompressor\"" : "") +
                  ">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"5\" NumberOfCells=\"3\">\n<Points>\n" +
                  array(arrays[0]) + "</Points>\n<Cells>\n" + array(arrays[1]) + array(arrays[2]) + array(arrays[3]) +
                  "</Cells>\n<CellData>\n" + array(arrays[4]) + "</CellData>\n</Piece>\n</UnstructuredGrid>\n";
  if (!appended.empty())
    x += "<AppendedData encoding=\"" + std::string(mode == "raw" ? "raw" : "base64") + "\">\n_" + appended +
         "\n</AppendedData>\n";
  return x + "</VTKFile>\n";
}

TEST(TetMeshRead, VtuBinaryCompressedAppendedAndBigEndian) {
  const std::string dir = test::temp_dir();
  for (const char* mode : {"binary", "zlib", "raw", "base64", "big"}) {
    const std::string path = dir + "/" + mode + ".vtu";
    spit(path, vtu_file(mode));
    SCOPED_TRACE(mode);
    expect_two_tets(read_tet_mesh(path));
  }
}

TEST(TetMeshRead, VtuAsciiWithTwoPiecesAndAFrame) {
  const std::string path = test::temp_dir() + "/two.vtu";
  auto piece = [](const std::string& pts, const std::string& conn, const std::string& mat) {
    return "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\"><Points><DataArray type=\"Float32\" "
           "NumberOfComponents=\"3\" format=\"ascii\">" + pts + "</DataArray></Points><Cells>"
           "<DataArray type=\"Int32\" Name=\"connectivity\">" + conn + "</DataArray>"
           "<DataArray type=\"Int32\" Name=\"offsets\">4</DataArray>"
           "<DataArray type=\"UInt8\" Name=\"types\">10</DataArray></Cells>"
           "<CellData><DataArray type=\"Float64\" Name=\"material\">" + mat + "</DataArray></CellData></Piece>";
  };
  spit(path, "<?xml version=\"1.0\"?>\n<!-- frame RAS SPACE=RAS -->\n<VTKFile type=\"UnstructuredGrid\">"
             "<UnstructuredGrid>" + piece("0 0 0 1 0 0 0 1 0 0 0 1", "0 1 2 3", "4") +
             piece("1 0 0 0 1 0 0 0 1 1 1 1", "0 1 2 3", "5") + "</UnstructuredGrid></VTKFile>");
  const LabelledTets r = read_tet_mesh(path);
  ASSERT_EQ(r.vertices.size(), 8u);
  EXPECT_EQ(r.vertices[1], Vec3(-1, 0, 0));  // RAS -> LPS
  EXPECT_EQ(r.vertices[7], Vec3(-1, -1, 1));
  EXPECT_EQ(r.tets, (std::vector<std::array<int, 4>>{{0, 1, 2, 3}, {4, 5, 6, 7}}));
  EXPECT_EQ(r.materials, (std::vector<int>{4, 5}));
}

TEST(TetMeshRead, LegacyVtk51And42AsMeshioWritesThem) {
  const std::string dir = test::temp_dir();
  spit(dir + "/a51.vtk", std::string("# vtk DataFile Version 5.1\nwritten by meshio v5.0.0\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                                     "POINTS 5 double\n") + kPoints +
                             "\n\nMETADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 1.7\n\n"  // VTK 9's writer
                             "CELLS 4 11\nOFFSETS vtktypeint64\n0\n4\n8\n11\nCONNECTIVITY vtktypeint64\n0 1 2 3 1 2 3 4 0 1 2\n"
                             "CELL_TYPES 3\n10\n10\n5\nCELL_DATA 3\nFIELD FieldData 1\nmaterial 1 3 vtktypeint64\n1 2 3\n");
  expect_two_tets(read_tet_mesh(dir + "/a51.vtk"));
  spit(dir + "/a42.vtk", std::string("# vtk DataFile Version 4.2\nx SPACE=LPS\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                                     "POINTS 5 float\n") + kPoints +
                             "\nCELLS 3 14\n4 0 1 2 3\n4 1 2 3 4\n3 0 1 2\nCELL_TYPES 3\n10 10 5\n"
                             "POINT_DATA 5\nSCALARS t float 1\nLOOKUP_TABLE default\n0 1 2 3 4\n"
                             "CELL_DATA 3\nSCALARS gmsh:physical int\nLOOKUP_TABLE default\n1 2 3\n"
                             "VECTORS v double\n0 0 0 1 1 1 2 2 2\n");
  expect_two_tets(read_tet_mesh(dir + "/a42.vtk"));
  // Triangles' label pairs from cell arrays label_a and label_b (as write_vtk names them), in ascending order.
  spit(dir + "/pairs.vtk", std::string("# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n") +
                               kPoints + "\nCELLS 3 14\n4 0 1 2 3\n4 1 2 3 4\n3 0 1 2\nCELL_TYPES 3\n10 10 5\nCELL_DATA 3\n"
                               "SCALARS material int 1\nLOOKUP_TABLE default\n1 2 0\nSCALARS label_a int 1\nLOOKUP_TABLE default\n"
                               "0 0 2\nSCALARS label_b int 1\nLOOKUP_TABLE default\n0 0 1\n");
  const LabelledTets pairs = read_tet_mesh(dir + "/pairs.vtk");
  expect_two_tets(pairs, false);
  EXPECT_EQ(pairs.triangle_labels, (std::vector<std::array<int, 2>>{{1, 2}}));
  // BINARY 5.1: big-endian values after each section line.
  std::string b = "# vtk DataFile Version 5.1\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n" +
                  raw(std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}, true) +
                  "\nCELLS 4 11\nOFFSETS vtktypeint64\n" + raw(std::vector<std::int64_t>{0, 4, 8, 11}, true) +
                  "\nCONNECTIVITY vtktypeint64\n" + raw(std::vector<std::int64_t>{0, 1, 2, 3, 1, 2, 3, 4, 0, 1, 2}, true) +
                  "\nCELL_TYPES 3\n" + raw(std::vector<std::int32_t>{10, 10, 5}, true) +
                  "\nCELL_DATA 3\nFIELD FieldData 1\nmaterial 1 3 vtktypeint32\n" +
                  raw(std::vector<std::int32_t>{1, 2, 3}, true) + "\n";
  spit(dir + "/b51.vtk", b);
  expect_two_tets(read_tet_mesh(dir + "/b51.vtk"));
}

TEST(TetMeshRead, Gmsh22AndGmsh41WithEntitiesAndBinary) {
  const std::string dir = test::temp_dir();
  spit(dir + "/a22.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 3 \"interface_1_2\"\n$EndPhysicalNames\n"
                         "$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n$Elements\n4\n"
                         "1 15 2 0 1 1\n2 4 2 1 1 1 2 3 4\n3 4 2 2 2 2 3 4 5\n4 2 2 3 3 1 2 3\n$EndElements\n");
  LabelledTets r = read_tet_mesh(dir + "/a22.msh");
  expect_two_tets(r, false);
  EXPECT_EQ(r.triangle_labels, (std::vector<std::array<int, 2>>{{1, 2}}));  // from the physical name
  // 4.1 with $Entities: volume entities 10 and 20 carry physical tags 1 and 2;
  // node tags are not contiguous.
  spit(dir + "/a41.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Comments\nframe RAS SPACE=RAS\n$EndComments\n"
                         "$Entities\n0 0 1 2\n3 0 0 0 1 1 0 1 3 0\n10 0 0 0 1 1 1 1 1 0\n20 0 0 0 1 1 1 1 2 0\n$EndEntities\n"
                         "$Nodes\n2 5 11 55\n3 10 0 4\n11\n22\n33\n44\n0 0 0\n-1 0 0\n0 -1 0\n0 0 1\n"
                         "3 20 0 1\n55\n-1 -1 1\n$EndNodes\n$Elements\n3 3 1 3\n3 10 4 1\n1 11 22 33 44\n"
                         "3 20 4 1\n2 22 33 44 55\n2 3 2 1\n3 11 22 33\n$EndElements\n");
  expect_two_tets(read_tet_mesh(dir + "/a41.msh"));
  // 4.1 binary, no $Entities (meshio writes none): the entity tag is the material.
  std::string b = "$MeshFormat\n4.1 1 8\n" + raw(std::vector<std::int32_t>{1}) + "\n$EndMeshFormat\n$Nodes\n" +
                  raw(std::vector<std::uint64_t>{1, 5, 1, 5}) + raw(std::vector<std::int32_t>{3, 0, 0}) +
                  raw(std::vector<std::uint64_t>{5, 1, 2, 3, 4, 5}) +
                  raw(std::vector<double>{0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}) + "\n$EndNodes\n$Elements\n" +
                  raw(std::vector<std::uint64_t>{3, 3, 1, 3}) + raw(std::vector<std::int32_t>{3, 1, 4}) +
                  raw(std::vector<std::uint64_t>{1, 1, 1, 2, 3, 4}) + raw(std::vector<std::int32_t>{3, 2, 4}) +
                  raw(std::vector<std::uint64_t>{1, 2, 2, 3, 4, 5}) + raw(std::vector<std::int32_t>{2, 3, 2}) +
                  raw(std::vector<std::uint64_t>{1, 3, 1, 2, 3}) + "\n$EndElements\n";
  spit(dir + "/b41.msh", b);
  expect_two_tets(read_tet_mesh(dir + "/b41.msh"));
  // 2.2 binary: per block (type, count, tags), then (number, tags..., nodes...).
  std::string b22 = "$MeshFormat\n2.2 1 8\n" + raw(std::vector<std::int32_t>{1}) + "\n$EndMeshFormat\n$Nodes\n5\n";
  for (int i = 0; i < 5; ++i) {
    const double xyz[5][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
    b22 += raw(std::vector<std::int32_t>{i + 1}) + raw(std::vector<double>{xyz[i][0], xyz[i][1], xyz[i][2]});
  }
  b22 += "\n$EndNodes\n$Elements\n3\n" + raw(std::vector<std::int32_t>{4, 2, 2, 1, 1, 1, 1, 2, 3, 4, 2, 2, 2, 2, 3, 4, 5}) +
         raw(std::vector<std::int32_t>{2, 1, 2, 3, 3, 3, 1, 2, 3}) + "\n$EndElements\n";
  spit(dir + "/b22.msh", b22);
  expect_two_tets(read_tet_mesh(dir + "/b22.msh"));
}

// ---- errors name the file, the place and what was expected ----

TEST(TetMeshRead, ClearErrors) {
  const std::string dir = test::temp_dir();
  auto err = [&](const std::string& name, const std::string& content) {
    spit(dir + "/" + name, content);
    return error_of([&] { read_tet_mesh(dir + "/" + name); });
  };
  EXPECT_TRUE(has(err("ansys.msh", "(1 \"meshio 5.0.0\")\n(2 3)\n"), "ANSYS"));
  EXPECT_TRUE(has(err("v3.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), "expected 4.1 or 2.2"));
  std::string e = err("node.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 0 0\n$EndNodes\n$Elements\n1\n"
                                  "1 4 2 1 1 1 1 1 99\n$EndElements\n");
  EXPECT_TRUE(has(e, "node.msh\": line 10: $Elements element 0: node 99 is not defined"));
  EXPECT_TRUE(has(err("hex.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n8\n1 0 0 0\n2 0 0 0\n3 0 0 0\n4 0 0 0\n"
                             "5 0 0 0\n6 0 0 0\n7 0 0 0\n8 0 0 0\n$EndNodes\n$Elements\n1\n1 5 0 1 2 3 4 5 6 7 8\n$EndElements\n"), "element type 5 is a 3-D element other than a tetrahedron"));
  EXPECT_TRUE(has(err("hex.vtk", std::string("# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 float\n") +
                                 "0 0 0 1 0 0 0 1 0 1 1 0 0 0 1 1 0 1 0 1 1 1 1 1\nCELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\n"), "cell 0 is a hexahedron (VTK type 12); expected tetrahedra only"));
  EXPECT_TRUE(has(err("frac.vtk", std::string("# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n") +
                                  kPoints + "\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\nCELL_DATA 1\nSCALARS material float\n"
                                  "LOOKUP_TABLE default\n1.5\n"), "cell array \"material\", cell 0: value 1.5 is not an int"));
  EXPECT_TRUE(has(err("range.vtk", std::string("# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n") +
                                   kPoints + "\nCELLS 1 5\n4 0 1 2 9\nCELL_TYPES 1\n10\n"), "cell 0: vertex 9 is out of range; expected an integer in [0, 5)"));
  EXPECT_TRUE(has(err("poly.vtk", "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 0 float\n"), "DATASET \"POLYDATA\"; expected UNSTRUCTURED_GRID"));
  EXPECT_TRUE(has(err("lz4.vtu", "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkLZ4DataCompressor\"><UnstructuredGrid/></VTKFile>"), "line 1: compressor \"vtkLZ4DataCompressor\" is not read"));
  EXPECT_TRUE(has(err("poly.vtu", "<VTKFile type=\"PolyData\"></VTKFile>"), "expected UnstructuredGrid"));
  EXPECT_TRUE(has(err("bad.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"), "not well-formed XML"));
  std::string few = vtu_file("binary");
  few.replace(few.find("NumberOfCells=\"3\""), 17, "NumberOfCells=\"4\"");
  EXPECT_TRUE(has(err("few.vtu", few), "DataArray \"offsets\": 12 bytes; expected 4 values of 4 bytes"));
  EXPECT_TRUE(has(err("empty.mesh", ""), "MeshVersionFormatted"));
  const std::string one_tet =
      "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"N\">"
      "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>"
      "<Cells><DataArray type=\"Int64\" Name=\"connectivity\">0 1 2 3</DataArray>"
      "<DataArray type=\"Int64\" Name=\"offsets\">4</DataArray>"
      "<DataArray type=\"Int64\" Name=\"types\">T</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
  auto vtu = [&](const std::string& n, const std::string& type) {
    std::string x = one_tet;
    x.replace(x.find("\"N\""), 3, "\"" + n + "\"");
    x.replace(x.find(">T<"), 3, ">" + type + "<");
    return x;
  };
  EXPECT_TRUE(has(err("ok.vtu", vtu("1", "10")), "(no error)"));
  EXPECT_TRUE(has(err("type.vtu", vtu("1", "1e18")), "cell 0: type 1e+18; expected a VTK cell type (0..255)"));
  EXPECT_TRUE(has(err("many.vtu", vtu("100000", "10")), "DataArray \"offsets\": 100000 values are more than the file holds"));
  EXPECT_TRUE(has(err("huge.vtu", vtu("1e15", "10")), "NumberOfCells \"1e15\"; expected a count no larger"));
}

// ---- truncated and corrupted files fail with an Error, never a crash ----

void expect_clean_failures(const std::string& path, const std::string& good) {
  const std::string ext = path.substr(path.rfind('.'));
  std::size_t failures = 0, tries = 0;
  const std::size_t step = std::max<std::size_t>(1, good.size() / 150);
  for (std::size_t n = 0; n < good.size(); n += step, ++tries) {
    spit(path, good.substr(0, n));
    try {
      read_tet_mesh(path);
    } catch (const Error&) {
      ++failures;
    }
  }
  // Nearly every truncation must be noticed (one that cuts only trailing
  // lines such as "End" may still read).
  EXPECT_GE(failures, tries * 9 / 10) << path;
  std::uint64_t s = 12345;
  for (int k = 0; k < 150; ++k) {
    std::string bad = good;
    for (int j = 0; j < 3; ++j) {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      const std::size_t at = std::size_t(s >> 33) % bad.size();
      bad[at] = char((s >> 13) & 0xff);
    }
    spit(path, bad);
    try {
      const LabelledTets t = read_tet_mesh(path);
      t.validate("corrupted " + ext);  // whatever reads must be a valid mesh
    } catch (const Error&) {
    }
  }
}

TEST(TetMeshRead, TruncatedAndCorruptedFilesFailCleanly) {
  const std::string dir = test::temp_dir();
  const LabelledTets t = sample();
  for (const char* ext : {".mesh", ".vtu", ".vtk", ".msh"}) {
    write_tet_mesh(t, dir + "/good" + ext);
    expect_clean_failures(dir + "/bad" + ext, slurp(dir + "/good" + ext));
  }
  TetWriteParams bin;
  bin.binary = true;
  write_tet_mesh(t, dir + "/goodb.vtk", bin);
  expect_clean_failures(dir + "/badb.vtk", slurp(dir + "/goodb.vtk"));
  for (const char* mode : {"zlib", "raw", "base64", "big"})
    expect_clean_failures(dir + "/bad_" + mode + ".vtu", vtu_file(mode));
}

}  // namespace
}  // namespace pm

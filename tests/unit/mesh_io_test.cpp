#include <gtest/gtest.h>

#include <cmath>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "pm/base/error.h"
#include "pm/io/mesh.h"
#include "pm/io/number_text.h"
#include "pm/io/ply.h"
#include "test_util.h"

namespace pm {
namespace {

void write_text(const std::string& path, const std::string& s) {
  std::ofstream f(path, std::ios::binary);
  f << s;
}

// Appends the bytes of v in big-endian (be) or little-endian order.
template <class T>
void put(std::string& out, T v, bool be) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  std::uint16_t one = 1;
  const bool host_le = *reinterpret_cast<unsigned char*>(&one) == 1;
  if (be == host_le) std::reverse(b, b + sizeof(T));
  out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

Mesh tetrahedron() {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

// Tetrahedron with normals, two vertex scalars and two face int properties;
// every value is representable in float.
Mesh labelled_tetrahedron() {
  Mesh m = tetrahedron();
  m.vertices[1] = {1.5, -0.25, 1e-3f};
  m.normals = {{0, 0, -1}, {0.5f, 0.25f, 0.125f}, {0, 1, 0}, {-1, 0, 0}};
  m.vertex_scalars["curv"] = {0.5, -1.25, 3.0, 1e6};
  m.vertex_scalars["alpha"] = {1, 2, 3, 4.75};
  m.face_ints["label_a"] = {0, 1, 2, -7};
  m.face_ints["label_b"] = {100000, 5, 5, 2147483647};
  return m;
}

void expect_same(const Mesh& a, const Mesh& b) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) EXPECT_EQ(a.vertices[i], b.vertices[i]) << "vertex " << i;
  ASSERT_EQ(a.normals.size(), b.normals.size());
  for (std::size_t i = 0; i < a.normals.size(); ++i) EXPECT_EQ(a.normals[i], b.normals[i]) << "normal " << i;
  EXPECT_EQ(a.faces, b.faces);
  EXPECT_EQ(a.vertex_scalars, b.vertex_scalars);
  EXPECT_EQ(a.face_ints, b.face_ints);
}

// -- PLY --------------------------------------------------------------------

class PlyRoundTrip : public ::testing::TestWithParam<bool> {};

TEST_P(PlyRoundTrip, KeepsNormalsScalarsAndFaceProperties) {
  const bool binary = GetParam();
  const Mesh m = labelled_tetrahedron();
  const std::string path = test::temp_dir() + "/t.ply";
  write_mesh(m, path, {binary});
  std::ifstream f(path, std::ios::binary);
  std::string first, format;
  std::getline(f, first);
  std::getline(f, format);
  // Face properties make the file ASCII whatever is asked (meshio, see pm/io/ply.h).
  EXPECT_EQ(format, binary && m.face_ints.empty() ? "format binary_little_endian 1.0" : "format ascii 1.0");
  expect_same(read_mesh(path), m);
}

INSTANTIATE_TEST_SUITE_P(AsciiAndBinary, PlyRoundTrip, ::testing::Values(false, true));

// The ASCII writers' numbers are printf's %.*g text, character for character
// (append_number formats them with std::to_chars), and read back to the value.
TEST(NumberText, IsPrintfsGeneralFormat) {
  std::mt19937_64 rng(7);
  std::vector<double> vs = {0.0, -0.0, 1.0, -1.0, 0.1, 1e-7, 123456789.0, 1e21, 1e-300, 5e-324, 1.7976931348623157e308,
                            0.5, 2.5, 1e16, 123456.789e-20, std::nan(""), HUGE_VAL, -HUGE_VAL};
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> ex(-40, 40);
  for (int k = 0; k < 20000; ++k) vs.push_back(std::ldexp(mant(rng), ex(rng)));
  for (double v : vs)
    for (int digits : {kFloatDigits, kDoubleDigits, 6}) {
      char b[64];
      std::snprintf(b, sizeof b, "%.*g", digits, v);
      std::string got;
      append_number(got, v, digits);
      ASSERT_EQ(got, std::string(b)) << digits;
      if (digits == kDoubleDigits && std::isfinite(v)) {
        ASSERT_EQ(std::strtod(got.c_str(), nullptr), v);
      }
    }
  for (int k = 0; k < 20000; ++k) {  // floats in 9 digits read back to the float
    const float f = float(std::ldexp(mant(rng), ex(rng)));
    ASSERT_EQ(std::strtof(number_text(double(f), kFloatDigits).c_str(), nullptr), f);
  }
}

TEST(Ply, PointSetHasNoFaceElement) {
  Mesh m;
  m.vertices = {{1, 2, 3}, {4, 5, 6}};
  const std::string path = test::temp_dir() + "/p.ply";
  write_ply(m, path, false);
  std::ifstream f(path);
  const std::string text((std::istreambuf_iterator<char>(f)), {});
  EXPECT_EQ(text.find("element face"), std::string::npos);
  expect_same(read_ply(path), m);
}

// write_ply's doubles option keeps every bit of positions, normals and
// scalars (ASCII %.17g and binary), where float rounds 1/sqrt(2) by ~1e-8.
TEST(Ply, DoublesKeepEveryBit) {
  Mesh m;
  const double z = 1 / std::sqrt(2.0);
  m.vertices = {{z, -z / 3, 1e-300}, {12345.678901234567, z * 1e-9, -z}};
  m.normals = {{0, 0, 1}, {z, z, 0}};
  m.vertex_scalars["residual"] = {1e-17, 2.5e-13};
  for (bool binary : {false, true}) {
    const std::string path = test::temp_dir() + "/d.ply";
    write_ply(m, path, binary, WorldFrame::lps, true);
    std::ifstream f(path);
    const std::string text((std::istreambuf_iterator<char>(f)), {});
    EXPECT_NE(text.find("property double x"), std::string::npos);
    EXPECT_NE(text.find("property double residual"), std::string::npos);
    const Mesh r = read_ply(path);
    ASSERT_EQ(r.vertices.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i)
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(r.vertices[i][c], m.vertices[i][c]) << binary;
        EXPECT_EQ(r.normals[i][c], m.normals[i][c]) << binary;
      }
    EXPECT_EQ(r.vertex_scalars.at("residual"), m.vertex_scalars.at("residual"));
  }
  // The float default rounds: 1/sqrt(2) comes back off by more than 1e-9.
  const std::string path = test::temp_dir() + "/f.ply";
  write_ply(m, path, true);
  EXPECT_GT(std::fabs(read_ply(path).vertices[0].x - z), 1e-9);
}

// ASCII numbers other tools write: a leading '+', exponents, hexadecimal,
// subnormals; each reads as strtod reads it (std::from_chars takes the plain
// ones, strtod the rest).
TEST(Ply, AsciiNumbersReadAsStrtodReadsThem) {
  const char* tok[9] = {"+1.5", "-2.25e+2", "0x1p-3", "1e-310", "3", ".5", "-0", "7.0000000000000001", "1E2"};
  std::string s = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
                  "property double z\nend_header\n";
  for (int k = 0; k < 9; ++k) s += std::string(tok[k]) + (k % 3 == 2 ? "\n" : " ");
  const std::string path = test::temp_dir() + "/tokens.ply";
  std::ofstream(path) << s;
  const Mesh r = read_ply(path);
  ASSERT_EQ(r.vertices.size(), 3u);
  for (int k = 0; k < 9; ++k) {
    const double got = r.vertices[std::size_t(k / 3)][k % 3];
    EXPECT_EQ(got, std::strtod(tok[k], nullptr)) << tok[k];
    EXPECT_EQ(std::signbit(got), std::signbit(std::strtod(tok[k], nullptr))) << tok[k];
  }
}

TEST(Ply, BigEndianWrittenByHand) {
  std::string s =
      "ply\nformat binary_big_endian 1.0\ncomment hand-made\n"
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar flag\nproperty double w\n"
      "element face 1\nproperty list uchar int vertex_indices\nproperty short label\nend_header\n";
  const float xyz[3][3] = {{1.5f, -2, 3}, {4, 5.25f, -6}, {7, 8, 9.125f}};
  for (int i = 0; i < 3; ++i) {
    for (float c : xyz[i]) put(s, c, true);
    put(s, std::uint8_t(200 + i), true);
    put(s, double(i) * 0.1, true);
  }
  put(s, std::uint8_t(3), true);
  for (std::int32_t i : {2, 0, 1}) put(s, i, true);
  put(s, std::int16_t(-300), true);
  const std::string path = test::temp_dir() + "/be.ply";
  write_text(path, s);

  const Mesh m = read_mesh(path);
  ASSERT_EQ(m.vertices.size(), 3u);
  EXPECT_EQ(m.vertices[0], Vec3(1.5, -2, 3));
  EXPECT_EQ(m.vertices[1], Vec3(4, 5.25, -6));
  EXPECT_EQ(m.vertices[2], Vec3(7, 8, 9.125));
  EXPECT_FALSE(m.has_normals());
  ASSERT_EQ(m.vertex_scalars.size(), 2u);
  EXPECT_EQ(m.vertex_scalars.at("flag"), (std::vector<double>{200, 201, 202}));
  EXPECT_EQ(m.vertex_scalars.at("w"), (std::vector<double>{0.0, 0.1, 0.2}));
  ASSERT_EQ(m.faces.size(), 1u);
  EXPECT_EQ(m.faces[0], (std::array<int, 3>{2, 0, 1}));
  EXPECT_EQ(m.face_ints.at("label"), std::vector<int>{-300});
}

TEST(Ply, EveryScalarTypeLittleEndian) {
  const char* types[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double",
                         "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"};
  std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n";
  s += "property float32 x\nproperty float64 y\nproperty int16 z\n";
  for (const char* t : types) s += std::string("property ") + t + " p_" + t + "\n";
  s += "end_header\n";
  put(s, 1.0f, false);
  put(s, 2.0, false);
  put(s, std::int16_t(3), false);
  for (int rep = 0; rep < 2; ++rep) {
    put(s, std::int8_t(-100), false);
    put(s, std::uint8_t(250), false);
    put(s, std::int16_t(-30000), false);
    put(s, std::uint16_t(60000), false);
    put(s, std::int32_t(-2000000000), false);
    put(s, std::uint32_t(4000000000u), false);
    put(s, 0.375f, false);
    put(s, 1e300, false);
  }
  const std::string path = test::temp_dir() + "/types.ply";
  write_text(path, s);
  const Mesh m = read_ply(path);
  ASSERT_EQ(m.vertices.size(), 1u);
  EXPECT_EQ(m.vertices[0], Vec3(1, 2, 3));
  const double expect[8] = {-100, 250, -30000, 60000, -2000000000.0, 4000000000.0, 0.375, 1e300};
  for (int i = 0; i < 16; ++i)
    EXPECT_EQ(m.vertex_scalars.at(std::string("p_") + types[i]).at(0), expect[i % 8]) << types[i];
}

TEST(Ply, SkipsOtherElementsAndFanTriangulatesQuads) {
  const std::string ascii =
      "ply\r\nformat ascii 1.0\r\n"
      "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
      "property list uchar float uv\n"  // list on vertices: skipped
      "element edge 2\nproperty int vertex1\nproperty list uchar int chain\nproperty int vertex2\n"
      "element face 2\nproperty list uchar uint vertex_index\nproperty list uchar float texcoord\n"
      "property float label_a\nend_header\n"
      "0 0 0 2 0.1 0.2\n1 0 0 0\n1 1 0 1 5\n0 1 0 0\n2 2 2 0\n"
      "0 3 1 2 3 1\n"
      "1 0 2\n"
      "4 0 1 2 3 0 6.6\n"
      "3 1 4 2 2 0.5 0.5 -2.4\n";
  const std::string path = test::temp_dir() + "/extra.ply";
  write_text(path, ascii);
  const Mesh m = read_ply(path);
  ASSERT_EQ(m.vertices.size(), 5u);
  EXPECT_EQ(m.vertices[2], Vec3(1, 1, 0));
  EXPECT_TRUE(m.vertex_scalars.empty());
  ASSERT_EQ(m.faces.size(), 3u);
  EXPECT_EQ(m.faces[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(m.faces[1], (std::array<int, 3>{0, 2, 3}));
  EXPECT_EQ(m.faces[2], (std::array<int, 3>{1, 4, 2}));
  EXPECT_EQ(m.face_ints.at("label_a"), (std::vector<int>{7, 7, -2}));

  // The same in binary: the skipped lists must be stepped over byte-exactly.
  std::string b =
      "ply\nformat binary_little_endian 1.0\n"
      "element vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
      "element edge 2\nproperty list ushort short chain\nproperty char tag\n"
      "element face 1\nproperty list int int vertex_indices\nend_header\n";
  for (int i = 0; i < 3; ++i)
    for (int c = 0; c < 3; ++c) put(b, double(i == c), false);
  put(b, std::uint16_t(3), false);
  for (std::int16_t k : {7, 8, 9}) put(b, k, false);
  put(b, std::int8_t(1), false);
  put(b, std::uint16_t(0), false);
  put(b, std::int8_t(2), false);
  put(b, std::int32_t(3), false);
  for (std::int32_t k : {0, 1, 2}) put(b, k, false);
  const std::string bpath = test::temp_dir() + "/extra_bin.ply";
  write_text(bpath, b);
  const Mesh mb = read_ply(bpath);
  ASSERT_EQ(mb.faces.size(), 1u);
  EXPECT_EQ(mb.faces[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(mb.vertices[1], Vec3(0, 1, 0));
}

// -- PLY bad input ------------------------------------------------------------

template <class E>
std::string error_of(const std::string& path) {
  try {
    read_mesh(path);
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for " << path;
  return "";
}

TEST(PlyBad, MissingFile) {
  const std::string msg = error_of<IoError>(test::temp_dir() + "/nope.ply");
  EXPECT_NE(msg.find("nope.ply"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no such file"), std::string::npos) << msg;
}

TEST(PlyBad, TruncatedBinary) {
  const std::string path = test::temp_dir() + "/trunc.ply";
  Mesh m = labelled_tetrahedron();
  m.face_ints.clear();  // with face properties the file would be ASCII (pm/io/ply.h)
  write_ply(m, path, true);
  // Cut into the last index of face 3 (its count still fits the bytes left).
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 2);
  const std::string msg = error_of<InputError>(path);
  EXPECT_NE(msg.find("trunc.ply"), std::string::npos) << msg;
  EXPECT_NE(msg.find("face 3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unexpected end of data"), std::string::npos) << msg;
}

TEST(PlyBad, FaceIndexOutOfRange) {
  const std::string path = test::temp_dir() + "/range.ply";
  write_text(path,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n");
  const std::string msg = error_of<InputError>(path);
  EXPECT_NE(msg.find("range.ply"), std::string::npos) << msg;
  EXPECT_NE(msg.find("face 1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("line 14"), std::string::npos) << msg;
  EXPECT_NE(msg.find("vertex index 3 is out of range; expected an integer in [0, 3)"), std::string::npos) << msg;
}

TEST(PlyBad, AbsurdCountFailsFast) {
  for (const char* fmt : {"binary_little_endian", "ascii"}) {
    const std::string path = test::temp_dir() + "/huge.ply";
    write_text(path, std::string("ply\nformat ") + fmt +
                         " 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
                         "property float z\nend_header\n0 0 0\n");
    const std::string msg = error_of<InputError>(path);
    EXPECT_NE(msg.find("1000000000000 vertex elements"), std::string::npos) << msg;
    EXPECT_NE(msg.find("6 bytes follow"), std::string::npos) << msg;
  }
}

TEST(PlyBad, GarbageHeaders) {
  const std::string dir = test::temp_dir();
  const std::pair<const char*, const char*> cases[] = {
      {"not a ply file\n", "does not start with \"ply\""},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "no end_header"},
      {"ply\nformat ebcdic 1.0\nend_header\n", "unknown format \"ebcdic\""},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "unknown type \"float128\""},
      {"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "malformed element line"},
      {"ply\nformat ascii 1.0\nbanana\nend_header\n", "unknown keyword \"banana\""},
      {"ply\nelement vertex 0\nend_header\n", "no format line"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
       "no scalar properties x, y and z"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
       "end_header\n1 2 three\n",
       "\"three\" is not a number"},
  };
  for (const auto& [text, expect] : cases) {
    const std::string path = dir + "/bad.ply";
    write_text(path, text);
    const std::string msg = error_of<InputError>(path);
    EXPECT_NE(msg.find(expect), std::string::npos) << "got: " << msg << "\nexpected: " << expect;
    EXPECT_NE(msg.find("bad.ply"), std::string::npos) << msg;
  }
}

TEST(PlyBad, WriteRejectsNamesThatBreakTheHeader) {
  Mesh m = tetrahedron();
  m.vertex_scalars["two words"] = {1, 2, 3, 4};
  EXPECT_THROW(write_mesh(m, test::temp_dir() + "/n.ply"), InputError);
  m.vertex_scalars.clear();
  m.vertex_scalars["x"] = {1, 2, 3, 4};
  EXPECT_THROW(write_mesh(m, test::temp_dir() + "/n.ply"), InputError);
  EXPECT_FALSE(std::filesystem::exists(test::temp_dir() + "/n.ply"));
}

// -- validate, dispatch, normals --------------------------------------------

TEST(Mesh, ValidateCatchesInconsistentSizesAndIndices) {
  Mesh m = tetrahedron();
  EXPECT_NO_THROW(m.validate("t"));
  m.faces[2][1] = 4;
  EXPECT_THROW(m.validate("t"), InputError);
  m = tetrahedron();
  m.normals.resize(3);
  EXPECT_THROW(m.validate("t"), InputError);
  m = tetrahedron();
  m.vertex_scalars["a"] = {1, 2};
  EXPECT_THROW(m.validate("t"), InputError);
  m = tetrahedron();
  m.face_ints["l"] = {1, 2, 3};
  try {
    m.validate("here");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "here: face property \"l\" has 3 values; expected 4 (one per face)");
  }
}

TEST(Mesh, UnknownExtensionIsUsageError) {
  EXPECT_THROW(read_mesh(test::temp_dir() + "/x.xyz"), UsageError);
  try {
    write_mesh(tetrahedron(), test::temp_dir() + "/x.vtx");
    ADD_FAILURE();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("expected one of .ply .vtp .vtk .mesh .obj .off .stl"), std::string::npos)
        << e.what();
  }
}

TEST(Mesh, VertexNormalsPointOutOfAClosedMesh) {
  Mesh m = tetrahedron();
  compute_vertex_normals(m);
  ASSERT_EQ(m.normals.size(), 4u);
  const Vec3 centroid{0.25, 0.25, 0.25};
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(norm(m.normals[i]), 1.0, 1e-12);
    EXPECT_GT(dot(m.normals[i], m.vertices[i] - centroid), 0) << i;
  }
  // Vertex 0 touches three right triangles of equal area: the normal is the
  // mean of -x, -y and -z.
  const double c = -1 / std::sqrt(3.0);
  EXPECT_NEAR(m.normals[0].x, c, 1e-12);
  EXPECT_NEAR(m.normals[0].y, c, 1e-12);
  EXPECT_NEAR(m.normals[0].z, c, 1e-12);
  // An isolated vertex gets a zero normal.
  m.vertices.push_back({5, 5, 5});
  compute_vertex_normals(m);
  EXPECT_EQ(m.normals[4], Vec3());
}

// -- OFF / OBJ / STL ----------------------------------------------------------

std::multiset<std::vector<double>> triangle_set(const Mesh& m) {
  // Each triangle as its corners, rotated so the smallest corner comes first
  // (keeps the winding).
  std::multiset<std::vector<double>> s;
  for (const auto& f : m.faces) {
    std::vector<std::vector<double>> c;
    for (int k = 0; k < 3; ++k) c.push_back({m.vertices[f[k]].x, m.vertices[f[k]].y, m.vertices[f[k]].z});
    const int first = int(std::min_element(c.begin(), c.end()) - c.begin());
    std::vector<double> t;
    for (int k = 0; k < 3; ++k) t.insert(t.end(), c[(first + k) % 3].begin(), c[(first + k) % 3].end());
    s.insert(t);
  }
  return s;
}

class CgalRoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(CgalRoundTrip, Tetrahedron) {
  Mesh m = tetrahedron();
  m.vertices[1] = {0.1, 2.5, -1.0 / 3};  // not exact in float: OFF/OBJ keep 17 digits
  const std::string ext = GetParam();
  for (bool binary : {true, false}) {
    const std::string path = test::temp_dir() + "/t" + ext;
    write_mesh(m, path, {binary});
    const Mesh r = read_mesh(path);
    EXPECT_TRUE(r.vertex_scalars.empty());
    ASSERT_EQ(r.vertices.size(), 4u) << ext;
    ASSERT_EQ(r.faces.size(), 4u) << ext;
    if (ext == ".stl") {
      // binary: float coordinates; corners merged, possibly in another order
      Mesh mf = m;
      if (binary)
        for (Vec3& v : mf.vertices) v = {float(v.x), float(v.y), float(v.z)};
      EXPECT_EQ(triangle_set(r), triangle_set(mf));
    } else {
      for (int i = 0; i < 4; ++i) EXPECT_EQ(r.vertices[i], m.vertices[i]) << ext << " vertex " << i;
      EXPECT_EQ(r.faces, m.faces) << ext;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, CgalRoundTrip, ::testing::Values(".off", ".obj", ".stl"),
                         [](const auto& info) { return info.param.substr(1); });

TEST(Cgal, OffQuadsAreFanTriangulatedAndObjNegativeIndicesWork) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/q.off", "OFF\n# a unit square\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  const Mesh q = read_mesh(dir + "/q.off");
  ASSERT_EQ(q.faces.size(), 2u);
  EXPECT_EQ(q.faces[1], (std::array<int, 3>{0, 2, 3}));
  write_text(dir + "/q.obj", "# square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf -4//1 -3//1 -2//1 -1//1\n");
  const Mesh o = read_mesh(dir + "/q.obj");
  ASSERT_EQ(o.faces.size(), 2u);
  EXPECT_EQ(o.faces[0], (std::array<int, 3>{0, 1, 2}));
}

TEST(CgalBad, MalformedFilesNameTheFile) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  write_text(dir + "/huge.off", "OFF\n1000000000000 1 0\n0 0 0\n");
  write_text(dir + "/trunc.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  write_text(dir + "/range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  write_text(dir + "/junk.obj", "v 0 0 0\nbanana 1 2\n");
  write_text(dir + "/trunc.stl", std::string(80, ' ') + std::string("\x05\0\0\0", 4) + std::string(30, '\0'));
  for (const char* name : {"range.off", "huge.off", "trunc.off", "range.obj", "junk.obj", "trunc.stl"}) {
    const std::string msg = error_of<InputError>(dir + "/" + name);
    EXPECT_NE(msg.find(name), std::string::npos) << msg;
  }
  EXPECT_NE(error_of<InputError>(dir + "/huge.off").find("1000000000000 vertices"), std::string::npos);
  Mesh points;
  points.vertices.push_back({0, 0, 0});
  EXPECT_THROW(write_mesh(points, dir + "/points.stl"), InputError);
}

// -- real data ------------------------------------------------------------------

class SharedMesh : public ::testing::TestWithParam<std::string> {};

TEST_P(SharedMesh, CountsMatchHeaderAndMeshIsClosed) {
  PM_REQUIRE_SHARED(path, "cgal-meshes/" + GetParam());
  std::ifstream f(path);
  std::string magic;
  std::size_t nv = 0, nf = 0;
  f >> magic >> nv >> nf;
  ASSERT_EQ(magic, "OFF");
  const Mesh m = read_mesh(path);
  EXPECT_EQ(m.vertices.size(), nv);
  EXPECT_EQ(m.faces.size(), nf);  // all triangles in these files
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : m.faces)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  std::size_t bad = 0;
  for (const auto& kv : edges) bad += kv.second != 2;
  EXPECT_EQ(bad, 0u) << "edges not in exactly two faces";
  EXPECT_EQ(edges.size() * 2, m.faces.size() * 3);
}

INSTANTIATE_TEST_SUITE_P(CgalMeshes, SharedMesh,
                         ::testing::Values("bunny00.off", "armadillo.off", "fandisk.off", "knot1.off"),
                         [](const auto& info) { return info.param.substr(0, info.param.find('.')); });

}  // namespace
}  // namespace pm

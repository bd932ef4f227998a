// Round trips and file contents of the VTK, MEDIT and Gmsh writers, the frame
// conversion, the format table and the output-extension check.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "pm/base/error.h"
#include "pm/io/medit.h"
#include "pm/io/mesh.h"
#include "pm/io/output_path.h"
#include "pm/io/ply.h"
#include "pm/io/tet_mesh.h"
#include "pm/io/vtk.h"
#include "test_util.h"

namespace pm {
namespace {

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), {});
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Coordinates with 17 significant digits that float would round: the VTK and
// MEDIT writers keep doubles exactly.
Mesh labelled_tetrahedron() {
  Mesh m;
  m.vertices = {{0.1, 0.2, 0.3}, {1.0000000001, 0, 0}, {0, 1.0 / 3.0, 0}, {0, 0, -2.5e-7}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  m.normals = {{0, 0, -1}, {0.6, 0.8, 0}, {0, 1, 0}, {-1, 0, 0}};
  m.vertex_scalars["curv"] = {0.5, -1.25, 1.0 / 7.0, 1e6};
  m.face_ints["label_a"] = {0, 0, 1, 1};
  m.face_ints["label_b"] = {1, 2, 2, 2};
  m.face_ints["pair"] = {0, 1, 2, 2};
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

class VtkRoundTrip : public ::testing::TestWithParam<bool> {};

TEST_P(VtkRoundTrip, KeepsEveryPropertyExactly) {
  const Mesh m = labelled_tetrahedron();
  const std::string path = test::temp_dir() + "/t.vtk";
  write_mesh(m, path, {GetParam()});
  const std::string text = slurp(path);
  EXPECT_EQ(text.rfind("# vtk DataFile Version 4.2\nparticlemesh", 0), 0u);
  EXPECT_NE(text.find("SPACE=LPS\n" + std::string(GetParam() ? "BINARY" : "ASCII") + "\nDATASET UNSTRUCTURED_GRID\n"),
            std::string::npos);
  EXPECT_NE(text.find("CELL_TYPES 4\n"), std::string::npos);
  EXPECT_NE(text.find("CELL_DATA 4\nSCALARS label_a int 1"), std::string::npos);
  expect_same(read_mesh(path), m);
}

INSTANTIATE_TEST_SUITE_P(AsciiAndBinary, VtkRoundTrip, ::testing::Values(false, true));

TEST(Vtk, PointSetIsWrittenAsVertices) {
  Mesh m;
  m.vertices = {{1, 2, 3}, {4, 5, 6}, {-7, 8.5, 9}};
  m.vertex_scalars["junction"] = {1, 2, 3};
  const std::string path = test::temp_dir() + "/p.vtk";
  write_mesh(m, path, {false});
  EXPECT_NE(slurp(path).find("CELLS 3 6\n1 0\n1 1\n1 2\nCELL_TYPES 3\n1\n1\n1\n"), std::string::npos);
  expect_same(read_mesh(path), m);
}

TEST(Vtk, ReadsPolydataAndRefusesTetrahedra) {
  // Legacy POLYDATA (as other programs write surfaces) reads as before; an
  // UNSTRUCTURED_GRID of tetrahedra is refused by cell.
  const std::string path = test::temp_dir() + "/pd.vtk";
  std::ofstream(path) << "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 4 double\n"
                         "0 0 0 1 0 0 0 1 0 1 1 0\nPOLYGONS 1 5\n4 0 1 3 2\nCELL_DATA 1\nSCALARS label_a int 1\n"
                         "LOOKUP_TABLE default\n7\n";
  const Mesh q = read_mesh(path);
  ASSERT_EQ(q.faces.size(), 2u);  // the quad fan-triangulated
  EXPECT_EQ(q.face_ints.at("label_a"), (std::vector<int>{7, 7}));
  std::ofstream(path) << "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n"
                         "0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
  try {
    read_mesh(path);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("CELL_TYPES cell 0: type 10 with 4 vertices"), std::string::npos) << e.what();
  }
}

TEST(Vtk, ReaderNamesWhatItDoesNotRead) {
  const std::string path = test::temp_dir() + "/g.vtk";
  std::ofstream(path) << "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n";
  try {
    read_mesh(path);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected POLYDATA or UNSTRUCTURED_GRID"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 1000 double\n0 0 0\n";
  EXPECT_THROW(read_mesh(path), InputError);  // counts beyond the file
  std::ofstream(path) << "# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 double\n0 0 0 1 0 0 0 1 0\n"
                         "POLYGONS 1 4\n3 0 1 7\n";
  EXPECT_THROW(read_mesh(path), InputError);  // index out of range
}

TEST(Vtp, StatesFrameAndCarriesCellAndPointData) {
  const Mesh m = labelled_tetrahedron();
  const std::string path = test::temp_dir() + "/t.vtp";
  write_mesh(m, path, {true, WorldFrame::ras});
  const std::string text = slurp(path);
  EXPECT_NE(text.find("<VTKFile type=\"PolyData\""), std::string::npos);
  EXPECT_NE(text.find("Name=\"SPACE\""), std::string::npos);
  EXPECT_NE(text.find("82 65 83 0"), std::string::npos);  // "RAS" as character codes
  EXPECT_NE(text.find("NumberOfPoints=\"4\""), std::string::npos);
  EXPECT_NE(text.find("NumberOfPolys=\"4\""), std::string::npos);
  EXPECT_EQ(count_of(text, "<DataArray type=\"Int32\""), 3u);  // label_a, label_b, pair
  EXPECT_NE(text.find("Name=\"label_b\" format=\"ascii\">\n1 2 2 2"), std::string::npos);
  EXPECT_NE(text.find("Name=\"Normals\" NumberOfComponents=\"3\""), std::string::npos);
  // RAS: x and y negated on write.
  EXPECT_NE(text.find("-0.10000000000000001 -0.20000000000000001 0.29999999999999999"), std::string::npos);
  EXPECT_THROW(read_mesh(path), UsageError);  // written, not read
}

TEST(Medit, LabelPairsBecomeTriangleReferencesAndBack) {
  const Mesh m = labelled_tetrahedron();
  const std::string path = test::temp_dir() + "/t.mesh";
  write_mesh(m, path);
  const std::string text = slurp(path);
  EXPECT_NE(text.find("# triangle reference 1: label_a 0 label_b 1\n"), std::string::npos);
  EXPECT_NE(text.find("# triangle reference 3: label_a 1 label_b 2\n"), std::string::npos);
  EXPECT_NE(text.find("Triangles\n4\n1 3 2 1\n"), std::string::npos);  // 1-based, reference of pair (0,1)
  Mesh want = m;
  want.normals.clear();  // MEDIT keeps geometry, triangles and their references
  want.vertex_scalars.clear();
  expect_same(read_mesh(path), want);
}

TEST(Medit, PlainReferencesRoundTrip) {
  Mesh m = labelled_tetrahedron();
  m.normals.clear();
  m.vertex_scalars.clear();
  m.face_ints = {{"ref", {4, 4, 9, -1}}};
  const std::string path = test::temp_dir() + "/r.mesh";
  write_mesh(m, path);
  expect_same(read_mesh(path), m);
}

TEST(Medit, MalformedInputIsAnInputError) {
  const std::string path = test::temp_dir() + "/bad.mesh";
  std::ofstream(path) << "MeshVersionFormatted 2\nDimension 3\nVertices\n2\n0 0 0 0\n1 1 1 0\nTriangles\n1\n1 2 3 0\nEnd\n";
  EXPECT_THROW(read_mesh(path), InputError);
  std::ofstream(path) << "MeshVersionFormatted 2\nDimension 3\nVertices\n99999999\n0 0 0 0\n";
  EXPECT_THROW(read_mesh(path), InputError);
}

TEST(Frame, RasNegatesXAndYOnWriteAndIsUndoneOnRead) {
  Mesh m = labelled_tetrahedron();
  const std::string dir = test::temp_dir();
  for (const char* ext : {".ply", ".vtk", ".mesh"}) {
    const std::string path = dir + "/f" + ext;
    write_mesh(m, path, {false, WorldFrame::ras});
    const std::string text = slurp(path);
    EXPECT_NE(text.find("SPACE=RAS"), std::string::npos) << ext;
    WorldFrame fr = WorldFrame::lps;
    Mesh raw = std::string(ext) == ".ply" ? read_ply(path, &fr) : std::string(ext) == ".vtk" ? read_vtk(path, &fr)
                                                                                          : read_medit(path, &fr);
    EXPECT_EQ(fr, WorldFrame::ras) << ext;
    ASSERT_EQ(raw.vertices.size(), m.vertices.size());
    // PLY stores float: compare within float rounding of each coordinate.
    const double tol = std::string(ext) == ".ply" ? 1e-7 : 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      EXPECT_NEAR(raw.vertices[i].x, -m.vertices[i].x, tol) << ext;
      EXPECT_NEAR(raw.vertices[i].y, -m.vertices[i].y, tol) << ext;
      EXPECT_NEAR(raw.vertices[i].z, m.vertices[i].z, tol) << ext;
    }
    if (!raw.normals.empty()) {
      EXPECT_NEAR(raw.normals[1].x, -0.6, tol) << ext;
      EXPECT_NEAR(raw.normals[1].y, -0.8, tol) << ext;
    }
    const Mesh back = read_mesh(path);  // converted into LPS
    for (std::size_t i = 0; i < m.vertices.size(); ++i)
      EXPECT_NEAR(back.vertices[i].x, m.vertices[i].x, tol) << ext;
    EXPECT_EQ(back.faces, m.faces) << ext;  // a rotation about z: the winding stays
  }
  EXPECT_NE(slurp(dir + "/f.ply").find("comment frame RAS SPACE=RAS\n"), std::string::npos);
  const std::string lps = dir + "/l.ply";
  write_mesh(m, lps);
  EXPECT_NE(slurp(lps).find("comment frame LPS SPACE=LPS\n"), std::string::npos);
  EXPECT_THROW(parse_frame("xyz"), UsageError);
  EXPECT_EQ(parse_frame("RAS"), WorldFrame::ras);
}

TEST(Ply, FacePropertiesAreWrittenAsAsciiForMeshio) {
  const std::string path = test::temp_dir() + "/a.ply";
  write_mesh(labelled_tetrahedron(), path, {true});
  EXPECT_NE(slurp(path).find("format ascii 1.0\n"), std::string::npos);
  Mesh plain = labelled_tetrahedron();
  plain.face_ints.clear();
  write_mesh(plain, path, {true});
  EXPECT_NE(slurp(path).find("format binary_little_endian 1.0\n"), std::string::npos);
}

// Two tetrahedra sharing the face (1,2,3): materials 1 and 2.
LabelledTets two_tets() {
  LabelledTets t;
  t.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  t.tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};
  t.materials = {1, 2};
  t.triangles = {{1, 2, 3}, {0, 2, 1}};
  t.triangle_labels = {{1, 2}, {0, 1}};
  return t;
}

TEST(TetMesh, EveryFormatByExtension) {
  const LabelledTets t = two_tets();
  const std::string d = test::temp_dir();
  write_tet_mesh(t, d + "/v.mesh");
  const std::string medit = slurp(d + "/v.mesh");
  EXPECT_NE(medit.find("Tetrahedra\n2\n1 2 3 4 1\n2 3 4 5 2\n"), std::string::npos) << medit;
  EXPECT_NE(medit.find("Triangles\n2\n2 3 4 2\n1 3 2 1\n"), std::string::npos) << medit;
  write_tet_mesh(t, d + "/v.vtu");
  const std::string vtu = slurp(d + "/v.vtu");
  EXPECT_NE(vtu.find("Name=\"material\" format=\"ascii\">\n1 2"), std::string::npos);
  EXPECT_NE(vtu.find("Name=\"types\" format=\"ascii\">\n10 10"), std::string::npos);
  write_tet_mesh(t, d + "/v.vtk");
  EXPECT_NE(slurp(d + "/v.vtk").find("DATASET UNSTRUCTURED_GRID\nPOINTS 5 double"), std::string::npos);
  write_tet_mesh(t, d + "/v.msh");
  const std::string msh = slurp(d + "/v.msh");
  EXPECT_EQ(msh.rfind("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n", 0), 0u);
  // Surface groups per label pair, tagged above the volume tags 1 and 2.
  EXPECT_NE(msh.find("$PhysicalNames\n4\n2 3 \"interface_0_1\"\n2 4 \"interface_1_2\"\n"
                     "3 1 \"material_1\"\n3 2 \"material_2\"\n$EndPhysicalNames\n"),
            std::string::npos)
      << msh;
  EXPECT_NE(msh.find("$Entities\n0 0 2 2\n3 0 0 0 1 1 0 1 3 0\n4 0 0 0 1 1 1 1 4 0\n"), std::string::npos) << msh;
  EXPECT_NE(msh.find("$Elements\n4 4 1 4\n"), std::string::npos) << msh;  // 4 blocks, tags 1..4
  EXPECT_NE(msh.find("3 2 4 1\n2 2 3 4 5\n"), std::string::npos);  // entity 2, tetrahedra, 1 element
  // Triangles (type 2) after the tetrahedra, element tags going on: (0, 1) then (1, 2).
  EXPECT_NE(msh.find("2 3 2 1\n3 1 3 2\n2 4 2 1\n4 2 3 4\n$EndElements\n"), std::string::npos) << msh;
}

TEST(TetMesh, GmshTagsArePositiveWhateverTheLabels) {
  LabelledTets t = two_tets();
  t.materials = {0, -3};
  const std::string path = test::temp_dir() + "/n.msh";
  write_tet_mesh(t, path);
  const std::string msh = slurp(path);
  EXPECT_NE(msh.find("2 3 \"interface_0_1\"\n2 4 \"interface_1_2\"\n3 1 \"material_-3\"\n3 2 \"material_0\"\n"),
            std::string::npos)
      << msh;
  // Positive labels are the volume tags; the surface tags go on above the largest.
  t.materials = {5, 9};
  write_tet_mesh(t, path);
  EXPECT_NE(slurp(path).find("2 10 \"interface_0_1\"\n2 11 \"interface_1_2\"\n3 5 \"material_5\"\n3 9 \"material_9\"\n"),
            std::string::npos)
      << slurp(path);
  // No room above the largest label: a clear error, no file.
  t.materials = {1, 2147483646};
  const std::string full = test::temp_dir() + "/full.msh";
  try {
    write_tet_mesh(t, full);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("material label 2147483646 leaves no room for the 2 surface tags"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(full));
}

TEST(TetMesh, UnknownExtensionIsAUsageErrorAndWritesNothing) {
  const std::string path = test::temp_dir() + "/v.obj";
  EXPECT_THROW(write_tet_mesh(two_tets(), path), UsageError);
  EXPECT_FALSE(std::filesystem::exists(path));
  LabelledTets bad = two_tets();
  bad.tets[1][3] = 5;
  EXPECT_THROW(write_tet_mesh(bad, test::temp_dir() + "/b.mesh"), InputError);
}

TEST(OutputPath, EachKindKnowsItsExtensions) {
  EXPECT_NO_THROW(check_output_path("", OutputKind::mesh, "-o"));
  EXPECT_NO_THROW(check_output_path("a.vtp", OutputKind::mesh, "-o"));
  EXPECT_NO_THROW(check_output_path("a.VTK", OutputKind::points, "-o"));
  EXPECT_NO_THROW(check_output_path("a.msh", OutputKind::tet_mesh, "--tets"));
  EXPECT_NO_THROW(check_output_path("a.nii.gz", OutputKind::volume, "output"));
  EXPECT_NO_THROW(check_output_path("-", OutputKind::json, "--stats"));
  EXPECT_THROW(check_output_path("a.mesh", OutputKind::points, "-o"), UsageError);
  EXPECT_THROW(check_output_path("a.obj", OutputKind::tet_mesh, "--tets"), UsageError);
  EXPECT_THROW(check_output_path("a.jpg", OutputKind::png, "-o"), UsageError);
  EXPECT_THROW(check_output_path("a.txt", OutputKind::json, "--stats"), UsageError);
  try {
    check_output_path("out/v.vtx", OutputKind::tet_mesh, "--tets");
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(),
                 "--tets \"out/v.vtx\": unknown tetrahedral mesh extension \".vtx\"; expected one of .mesh .vtu .vtk .msh");
  }
  EXPECT_EQ(output_extensions(OutputKind::mesh), ".ply .vtp .vtk .mesh .obj .off .stl");
  EXPECT_EQ(output_extensions(OutputKind::points), ".ply .vtp .vtk");
}

}  // namespace
}  // namespace pm

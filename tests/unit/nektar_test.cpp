// Nektar++ reader (pm/io/nektar.h): generated meshes and fields, plain and
// compressed, the shared Nektar++ test cases, and every bad input of issue #18.
#include "pm/io/nektar.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "nektar_fixtures.h"
#include "pm/base/error.h"
#include "pm/field/hp_field.h"
#include "test_util.h"

namespace pm {
namespace {

using test::GenBlock;
using test::GenMesh;

// Two tetrahedra sharing a face: A = (a0 a1 a2 a3), B = (a1 a2 a3 b3), B's
// face 0 being A's face 2.
GenMesh two_tets() {
  GenMesh m;
  const int a0 = m.vertex({0, 0, 0}), a1 = m.vertex({1, 0, 0}), a2 = m.vertex({0, 1, 0}), a3 = m.vertex({0, 0, 1});
  const int b3 = m.vertex({1, 1, 1});
  m.add_tet({a0, a1, a2, a3});
  m.add_tet({a1, a2, a3, b3});
  return m;
}

// Two unit hexahedra side by side along x (second one with a different local
// orientation: its local vertex 0 is at (2, 1, 0)).
GenMesh two_hexes() {
  GenMesh m;
  int v[3][2][2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) v[i][j][k] = m.vertex({double(i), double(j), double(k)});
  m.add_hex({v[0][0][0], v[1][0][0], v[1][1][0], v[0][1][0], v[0][0][1], v[1][0][1], v[1][1][1], v[0][1][1]});
  // Rotated 180 degrees about z: local x runs towards -x.
  m.add_hex({v[2][1][0], v[1][1][0], v[1][0][0], v[2][0][0], v[2][1][1], v[1][1][1], v[1][0][1], v[2][0][1]});
  return m;
}

std::string write(const std::string& name, const std::string& text) {
  const std::string p = test::temp_dir() + "/" + name;
  test::write_text(p, text);
  return p;
}

// Expect InputError whose message names the file and contains `what`.
template <class F>
void expect_input_error(F&& f, const std::string& path, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "no error for " << path << " (expected: " << what << ")";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  }
}

TEST(Nektar, B64zRoundTripAndNektarPadding) {
  std::vector<double> v = {1.5, -2.25, 1e-300, 3.0};
  const std::string s = nektar_b64z_encode(v.data(), v.size() * 8);
  EXPECT_EQ(s.find('='), std::string::npos);
  EXPECT_EQ(s.size() % 4, 0u);
  const auto back = nektar_b64z_decode(s, "t");
  ASSERT_EQ(back.size(), v.size() * 8);
  EXPECT_EQ(std::memcmp(back.data(), v.data(), back.size()), 0);
}

TEST(Nektar, PlainAndCompressedMeshAgreeAndLocalOrderIsDerived) {
  for (bool compressed : {false, true}) {
    const GenMesh g = two_tets();
    const std::string p = write(compressed ? "tets_z.xml" : "tets.xml", test::mesh_xml(g, compressed));
    const NektarMesh m = read_nektar_mesh(p);
    ASSERT_EQ(m.elements.size(), 2u);
    EXPECT_EQ(m.vertices.size(), 5u);
    EXPECT_EQ(m.edges.size(), 9u);
    EXPECT_EQ(m.faces.size(), 7u);
    // Local vertex order as built, although the vertex ids are scrambled and
    // every other edge is listed backwards.
    const std::array<Vec3, 4> want_b = {Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}, Vec3{1, 1, 1}};
    for (int k = 0; k < 4; ++k) EXPECT_EQ(m.vertex(m.elements[1].verts[k]), want_b[k]) << k;
    EXPECT_EQ(m.vertex(m.elements[0].verts[0]), (Vec3{0, 0, 0}));
  }
  const GenMesh h = two_hexes();
  for (bool compressed : {false, true}) {
    const std::string p = write(compressed ? "hex_z.xml" : "hex.xml", test::mesh_xml(h, compressed));
    const NektarMesh m = read_nektar_mesh(p);
    ASSERT_EQ(m.elements.size(), 2u);
    EXPECT_EQ(m.faces.size(), 11u);
    EXPECT_EQ(m.vertex(m.elements[1].verts[0]), (Vec3{2, 1, 0}));
    EXPECT_EQ(m.vertex(m.elements[1].verts[6]), (Vec3{1, 0, 1}));
  }
}

TEST(Nektar, FieldBlocksIdsAndLayout) {
  // Two blocks, ids "1" and "0", two fields: data [field][element][mode].
  GenBlock b0, b1;
  b0.fields = b1.fields = "u,p";
  b0.ids = "1";
  b1.ids = "0-0";
  b1.compressed_attr = false;  // chan3D.fld has no COMPRESSED attribute either
  for (int f = 0; f < 2; ++f)
    for (int k = 0; k < 64; ++k) {
      b0.coeffs.push_back(100 * f + k);
      b1.coeffs.push_back(-100 * f - k);
    }
  const std::string p = write("two.fld", test::field_xml({b0, b1}));
  const NektarField fld = read_nektar_field(p);
  ASSERT_EQ(fld.names, (std::vector<std::string>{"u", "p"}));
  ASSERT_EQ(fld.elements.size(), 2u);
  const auto& e1 = fld.elements[fld.element_index.at(1)];
  EXPECT_EQ(e1.ncoeffs, 64);
  EXPECT_EQ(e1.coeffs[64 + 5], 105);
  EXPECT_EQ(fld.elements[fld.element_index.at(0)].coeffs[64 + 7], -107);
  EXPECT_EQ(fld.variable("p"), 1);
  EXPECT_THROW(fld.variable("w"), UsageError);
  EXPECT_EQ(nektar_num_coeffs(NektarShape::Tetrahedron, {4, 4, 4}), 20);
  EXPECT_EQ(nektar_num_coeffs(NektarShape::Tetrahedron, {3, 3, 3}), 10);
  EXPECT_EQ(nektar_num_coeffs(NektarShape::Tetrahedron, {2, 3, 4}), (4 + 3 + 2) + (3 + 2));
}

TEST(Nektar, SharedTestCasesRead) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  struct Case {
    const char* name;
    std::size_t verts, edges, faces, elems;
    NektarShape shape;
    int modes;
  };
  for (const Case& c : {Case{"Tet_channel_m3", 27, 98, 120, 48, NektarShape::Tetrahedron, 3},
                        Case{"chan3D", 8, 19, 18, 6, NektarShape::Tetrahedron, 4},
                        Case{"Hex_channel_C0helmsmoothing", 27, 54, 36, 8, NektarShape::Hexahedron, 4}}) {
    const NektarMesh m = read_nektar_mesh(dir + "/" + c.name + ".xml");
    const NektarField f = read_nektar_field(dir + "/" + c.name + ".fld");
    EXPECT_EQ(m.vertices.size(), c.verts) << c.name;
    EXPECT_EQ(m.edges.size(), c.edges) << c.name;
    EXPECT_EQ(m.faces.size(), c.faces) << c.name;
    ASSERT_EQ(m.elements.size(), c.elems) << c.name;
    EXPECT_EQ(f.elements.size(), c.elems) << c.name;
    EXPECT_EQ(f.names, (std::vector<std::string>{"u", "v", "w", "p"})) << c.name;
    for (const auto& e : f.elements) {
      EXPECT_EQ(e.shape, c.shape);
      EXPECT_EQ(e.modes, (std::array<int, 3>{c.modes, c.modes, c.modes}));
    }
    EXPECT_NO_THROW(check_field_matches_mesh(f, m)) << c.name;
    EXPECT_EQ(m.expansion_modes, c.modes);
  }
}

// ---- bad input ---------------------------------------------------------------

TEST(NektarBadInput, MalformedXml) {
  std::string xml = test::mesh_xml(two_tets(), false);
  const std::string p = write("bad.xml", xml.substr(0, xml.size() / 2));
  expect_input_error([&] { read_nektar_mesh(p); }, p, "malformed XML");
  const std::string q = write("bad.fld", "<NEKTAR><ELEMENTS FIELDS=\"u\"");
  expect_input_error([&] { read_nektar_field(q); }, q, "malformed XML");
  const std::string r = write("notnek.xml", "<?xml version=\"1.0\"?><OTHER/>");
  expect_input_error([&] { read_nektar_mesh(r); }, r, "no NEKTAR root");
}

TEST(NektarBadInput, MissingSection) {
  std::string xml = test::mesh_xml(two_tets(), false);
  const auto a = xml.find("    <EDGE>"), b = xml.find("</EDGE>") + 8;
  const std::string p = write("noedge.xml", xml.substr(0, a) + xml.substr(b));
  expect_input_error([&] { read_nektar_mesh(p); }, p, "no EDGE section");
  const std::string q = write("noelements.fld", "<NEKTAR><Metadata/></NEKTAR>");
  expect_input_error([&] { read_nektar_field(q); }, q, "no ELEMENTS block");
  const std::string r = write("nogeom.xml", "<NEKTAR><EXPANSIONS/></NEKTAR>");
  expect_input_error([&] { read_nektar_mesh(r); }, r, "no GEOMETRY");
  GenBlock blk;
  blk.coeffs.assign(64, 1.0);
  std::string fx = test::field_xml({blk});
  fx.replace(fx.find(" BASIS="), std::string(" BASIS=\"Modified_A,Modified_A,Modified_A\"").size(), "");
  const std::string s = write("nobasis.fld", fx);
  expect_input_error([&] { read_nektar_field(s); }, s, "no BASIS attribute");
}

TEST(NektarBadInput, UnknownShapeAndBasis) {
  std::string xml = test::mesh_xml(two_tets(), false);
  std::string prism = xml, unknown = xml;
  prism.replace(prism.find("<A ID=\"1\">"), 10, "<R ID=\"1\">");
  prism.replace(prism.find("</A>\n    </ELEMENT>"), 4, "</R>");
  const std::string p = write("prism.xml", prism);
  expect_input_error([&] { read_nektar_mesh(p); }, p, "prism elements (R) are not supported");
  unknown.replace(unknown.find("<A ID=\"1\">"), 10, "<X ID=\"1\">");
  unknown.replace(unknown.find("</A>\n    </ELEMENT>"), 4, "</X>");
  const std::string q = write("unknown.xml", unknown);
  expect_input_error([&] { read_nektar_mesh(q); }, q, "unknown element type <X>");
  std::string face = xml;
  face.replace(face.find("<T ID=\"0\">"), 10, "<Z ID=\"0\">");
  face.replace(face.find("</T>"), 4, "</Z>");
  const std::string r = write("face.xml", face);
  expect_input_error([&] { read_nektar_mesh(r); }, r, "unknown face type <Z>");

  GenBlock blk;
  blk.coeffs.assign(64, 1.0);
  blk.shape = "Prism";
  const std::string s = write("shape.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(s); }, s, "SHAPE=\"Prism\" is not supported");
  blk.shape = "Hexahedron";
  blk.basis = "GLL_Lagrange,GLL_Lagrange,GLL_Lagrange";
  const std::string t = write("basis.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(t); }, t, "BASIS=\"GLL_Lagrange,GLL_Lagrange,GLL_Lagrange\"");
}

TEST(NektarBadInput, ModeCountMismatch) {
  GenBlock blk;
  blk.coeffs.assign(63, 1.0);
  const std::string p = write("modes.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(p); }, p, "63 coefficients for 1 elements x 1 fields; expected 64");
  blk.coeffs.assign(64, 1.0);
  blk.modes = "UNIORDER:4,4";
  const std::string q = write("modes2.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(q); }, q, "NUMMODESPERDIR has 2 numbers; expected 3");
  blk.modes = "4,4,4";
  const std::string r = write("modes3.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(r); }, r, "expected \"UNIORDER:P,Q,R\"");
  // Tetrahedra need P <= Q <= R.
  blk.shape = "Tetrahedron";
  blk.basis = "Modified_A,Modified_B,Modified_C";
  blk.modes = "UNIORDER:4,3,3";
  const std::string s = write("modes4.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(s); }, s, "expected P <= Q <= R");
}

TEST(NektarBadInput, ElementIdsTheMeshLacks) {
  const std::string mp = write("m.xml", test::mesh_xml(two_hexes(), true));
  GenBlock blk;
  blk.ids = "0-2";
  blk.coeffs.assign(3 * 64, 0.5);
  const std::string fp = write("f.fld", test::field_xml({blk}));
  const NektarMesh m = read_nektar_mesh(mp);
  const NektarField f = read_nektar_field(fp);
  expect_input_error([&] { check_field_matches_mesh(f, m); }, fp, "element 2 is not in the mesh");
  expect_input_error([&] { HpField(m, f, "u"); }, fp, "element 2 is not in the mesh");
  // And a mesh element without coefficients.
  blk.ids = "1";
  blk.coeffs.assign(64, 0.5);
  const std::string gp = write("g.fld", test::field_xml({blk}));
  expect_input_error([&] { HpField(m, read_nektar_field(gp), "u"); }, gp, "mesh element 0 has no coefficients");
  // A shape mismatch.
  blk.shape = "Tetrahedron";
  blk.basis = "Modified_A,Modified_B,Modified_C";
  blk.coeffs.assign(20, 0.5);
  const std::string hp = write("h.fld", test::field_xml({blk}));
  expect_input_error([&] { check_field_matches_mesh(read_nektar_field(hp), m); }, hp, "is a Tetrahedron in the field");
  // Ids given twice.
  GenBlock a, b;
  a.coeffs.assign(64, 1.0);
  b.coeffs.assign(64, 1.0);
  const std::string dp = write("dup.fld", test::field_xml({a, b}));
  expect_input_error([&] { read_nektar_field(dp); }, dp, "element 0 appears twice");
  a.ids = "3-1";
  const std::string ep = write("range.fld", test::field_xml({a}));
  expect_input_error([&] { read_nektar_field(ep); }, ep, "ID range \"3-1\"");
}

TEST(NektarBadInput, TruncatedBase64AndZlib) {
  GenBlock blk;
  blk.coeffs.assign(64, 0.25);
  const std::string good = test::field_xml({blk});
  const auto a = good.find("BITSIZE=\"64\">") + 13, b = good.find("</ELEMENTS>");
  const std::string data = good.substr(a, b - a);
  // One character off the end: a base64 length of 4k+3 is still decodable, so cut
  // to 4k+1, which is not.
  std::string cut1 = data.substr(0, (data.size() / 4 - 1) * 4 + 1);
  const std::string p = write("b64.fld", good.substr(0, a) + cut1 + good.substr(b));
  expect_input_error([&] { read_nektar_field(p); }, p, "truncated base64");
  // Half of the data: valid base64 of a zlib stream that ends early.
  std::string half = data.substr(0, (data.size() / 8) * 4);
  const std::string q = write("zlib.fld", good.substr(0, a) + half + good.substr(b));
  expect_input_error([&] { read_nektar_field(q); }, q, "truncated zlib data");
  // A bad character and a corrupt stream.
  std::string bad = data;
  bad[5] = '*';
  const std::string r = write("char.fld", good.substr(0, a) + bad + good.substr(b));
  expect_input_error([&] { read_nektar_field(r); }, r, "bad base64 character \"*\"");
  std::string flip = data;
  flip[0] = flip[0] == 'A' ? 'B' : 'A';
  const std::string s = write("corrupt.fld", good.substr(0, a) + flip + good.substr(b));
  expect_input_error([&] { read_nektar_field(s); }, s, "zlib data");
  // The same in a compressed mesh section.
  std::string mx = test::mesh_xml(two_hexes(), true);
  const auto va = mx.find("BITSIZE=\"64\">") + 13, vb = mx.find("</VERTEX>");
  mx = mx.substr(0, va) + mx.substr(va, (vb - va) / 2) + mx.substr(vb);
  const std::string t = write("vert.xml", mx);
  expect_input_error([&] { read_nektar_mesh(t); }, t, "VERTEX");
}

TEST(NektarBadInput, NanCoefficients) {
  GenBlock blk;
  blk.fields = "u,p";
  blk.coeffs.assign(128, 0.25);
  blk.coeffs[64 + 9] = std::numeric_limits<double>::quiet_NaN();
  const std::string p = write("nan.fld", test::field_xml({blk}));
  expect_input_error([&] { read_nektar_field(p); }, p, "non-finite coefficient (nan) of field \"p\" in element 0, mode 9");
  GenMesh g = two_tets();
  g.verts[2].second.y = std::numeric_limits<double>::infinity();
  const std::string q = write("infvert.xml", test::mesh_xml(g, true));
  expect_input_error([&] { read_nektar_mesh(q); }, q, "non-finite coordinate");
}

TEST(NektarBadInput, DanglingReferencesAndBrokenElements) {
  std::string xml = test::mesh_xml(two_tets(), false);
  std::string dangling = xml;
  dangling.replace(dangling.find("<A ID=\"0\">"), 10, "<A ID=\"0\"> 99 ");
  const std::string p = write("dangling.xml", dangling);
  expect_input_error([&] { read_nektar_mesh(p); }, p, "has 5 entries; expected 4");
  std::string dangling2 = xml;
  const auto at = dangling2.find("<A ID=\"0\">") + 10;
  dangling2.replace(at, dangling2.find("</A>", at) - at, " 0 1 2 99 ");
  const std::string q = write("dangling2.xml", dangling2);
  expect_input_error([&] { read_nektar_mesh(q); }, q, "face 99, which is not in FACE");
  // Faces in the wrong order do not make a Nektar++ tetrahedron.
  std::string order = xml;
  const auto ot = order.find("<A ID=\"0\">") + 10;
  order.replace(ot, order.find("</A>", ot) - ot, " 2 1 0 3 ");
  const std::string r = write("order.xml", order);
  expect_input_error([&] { read_nektar_mesh(r); }, r, "tetrahedron A 0");
}

TEST(NektarBadInput, CurvedElementsReadAndRefusedByName) {
  GenMesh g = two_hexes();
  g.curved =
      "    <CURVED>\n      <E ID=\"0\" EDGEID=\"3\" TYPE=\"PolyEvenlySpaced\" NUMPOINTS=\"3\"> 0 0 0  0.5 0.1 0  1 0 0 "
      "</E>\n    </CURVED>\n";
  const std::string p = write("curved.xml", test::mesh_xml(g, false));
  const NektarMesh m = read_nektar_mesh(p);
  ASSERT_EQ(m.curved_edges.size(), 1u);
  EXPECT_EQ(m.curved_edges[0].entity, 3);
  EXPECT_EQ(m.curved_edges[0].points.size(), 3u);
  EXPECT_EQ(m.curved_edges[0].points[1], (Vec3{0.5, 0.1, 0}));
  GenBlock blk;
  blk.ids = "0-1";
  blk.coeffs.assign(128, 1.0);
  const NektarField f = read_nektar_field(write("c.fld", test::field_xml({blk})));
  expect_input_error([&] { HpField(m, f, "u"); }, p, "has curved edge 3; curved elements are not supported yet");
  // A wrong point count.
  g.curved = "    <CURVED><E ID=\"0\" EDGEID=\"3\" TYPE=\"PolyEvenlySpaced\" NUMPOINTS=\"3\"> 0 0 0 1 0 0 </E></CURVED>\n";
  const std::string q = write("curved2.xml", test::mesh_xml(g, false));
  expect_input_error([&] { read_nektar_mesh(q); }, q, "6 numbers; expected 3 x NUMPOINTS = 9");
}

TEST(NektarBadInput, DegenerateElementRefusedByHpField) {
  GenMesh g;
  const int a = g.vertex({0, 0, 0}), b = g.vertex({1, 0, 0}), c = g.vertex({0, 1, 0}), d = g.vertex({1, 1, 0});
  g.add_tet({a, b, c, d});  // flat
  const std::string p = write("flat.xml", test::mesh_xml(g, false));
  GenBlock blk;
  blk.shape = "Tetrahedron";
  blk.basis = "Modified_A,Modified_B,Modified_C";
  blk.modes = "UNIORDER:2,2,2";
  blk.coeffs.assign(4, 1.0);
  const NektarField f = read_nektar_field(write("flat.fld", test::field_xml({blk})));
  expect_input_error([&] { HpField(read_nektar_mesh(p), f, "u"); }, p, "tetrahedron 0 is degenerate (Jacobian determinant 0)");
}

TEST(NektarBadInput, MissingFileAndFolder) {
  EXPECT_THROW(read_nektar_mesh(test::temp_dir() + "/none.xml"), IoError);
  EXPECT_THROW(read_nektar_field(test::temp_dir()), IoError);
}

}  // namespace
}  // namespace pm

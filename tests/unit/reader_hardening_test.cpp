// Reader hardening (issue 7): absurd headers fail fast with a clear message
// before any large allocation, and every input the fuzzers found crashing,
// leaking, hanging or exhausting memory (tests/data/regress/) is now refused
// cleanly. Complements the bad-input tests of volume_io_test and mesh_io_test.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "pm/base/error.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/io/volume_io.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

/// Expect fn() to throw InputError whose message contains every one of `parts`.
template <class F>
void expect_input_error(F&& fn, std::initializer_list<std::string> parts) {
  try {
    fn();
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    for (const std::string& p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected InputError, got: " << e.what();
  }
}

// --- NIfTI-1 headers written byte by byte ------------------------------------
std::string nifti_header(const std::int16_t dim[8], const float pixdim[8], std::int16_t datatype = 16,
                         std::int16_t bitpix = 32) {
  std::string h(352, '\0');
  const std::int32_t sizeof_hdr = 348;
  std::memcpy(&h[0], &sizeof_hdr, 4);
  std::memcpy(&h[40], dim, 16);
  std::memcpy(&h[70], &datatype, 2);
  std::memcpy(&h[72], &bitpix, 2);
  std::memcpy(&h[76], pixdim, 32);
  const float vox_offset = 352;
  std::memcpy(&h[108], &vox_offset, 4);
  std::memcpy(&h[344], "n+1\0", 4);
  return h;
}

TEST(ReaderHardening, NiftiAbsurdHeaders) {
  const std::string dir = test::temp_dir();
  const float unit[8] = {1, 1, 1, 1, 1, 1, 1, 1};
  // 30000^3 float voxels (108 TB) in a 356-byte file.
  const std::int16_t huge[8] = {3, 30000, 30000, 30000, 1, 1, 1, 1};
  write_bytes(dir + "/huge.nii", nifti_header(huge, unit) + "abcd");
  expect_input_error([&] { read_volume(dir + "/huge.nii"); }, {"huge.nii"});
  // 2000^3 voxels: under the voxel limit, far beyond the file.
  const std::int16_t big[8] = {3, 2000, 2000, 2000, 1, 1, 1, 1};
  write_bytes(dir + "/big.nii", nifti_header(big, unit) + "abcd");
  expect_input_error([&] { read_volume(dir + "/big.nii"); }, {"big.nii"});
  // Dimension 0 and a negative axis size. (Zero or non-finite pixdim values are
  // replaced by 1 inside nifticlib, so spacing is checked on its result.)
  const std::int16_t zero[8] = {0, 1, 1, 1, 1, 1, 1, 1};
  write_bytes(dir + "/zero.nii", nifti_header(zero, unit) + "abcd");
  expect_input_error([&] { read_volume(dir + "/zero.nii"); }, {"zero.nii", "dim[0]"});
  const std::int16_t neg[8] = {3, 2, -2, 1, 1, 1, 1, 1};
  write_bytes(dir + "/neg.nii", nifti_header(neg, unit) + std::string(16, 'a'));
  expect_input_error([&] { read_volume(dir + "/neg.nii"); }, {"neg.nii", "dim[2] is -2"});
}

TEST(ReaderHardening, NrrdOverflowingAndZeroDimensions) {
  const std::string dir = test::temp_dir();
  // Each size is 2^32: the product overflows 64 bits.
  write_bytes(dir + "/ovf.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 4294967296 4294967296 4294967296\n"
                                 "encoding: raw\n\n0123");
  expect_input_error([&] { read_volume(dir + "/ovf.nrrd"); }, {"ovf.nrrd"});
  write_bytes(dir + "/d0.nrrd", "NRRD0004\ntype: float\ndimension: 0\nencoding: raw\n\n0123");
  expect_input_error([&] { read_volume(dir + "/d0.nrrd"); }, {"d0.nrrd"});
  // ("spacings: 1 nan 1" is valid NRRD: nan means unknown, read as 1.)
}

TEST(ReaderHardening, MetaImageOverflowingAndNegativeSizes) {
  const std::string dir = test::temp_dir();
  write_bytes(dir + "/ovf.mha", "NDims = 3\nDimSize = 18446744073709551615 18446744073709551615 2\n"
                                "ElementType = MET_FLOAT\nElementDataFile = LOCAL\n0123");
  expect_input_error([&] { read_volume(dir + "/ovf.mha"); }, {"ovf.mha"});
  write_bytes(dir + "/neg.mha", "NDims = 3\nDimSize = 2 -2 2\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n0123");
  expect_input_error([&] { read_volume(dir + "/neg.mha"); }, {"neg.mha"});
  write_bytes(dir + "/nd0.mha", "NDims = 0\nDimSize = \nElementType = MET_FLOAT\nElementDataFile = LOCAL\n0123");
  expect_input_error([&] { read_volume(dir + "/nd0.mha"); }, {"nd0.mha"});
  write_bytes(dir + "/sp.mha", "NDims = 3\nDimSize = 1 1 1\nElementSpacing = 1 1 -0.5\nElementType = MET_UCHAR\n"
                               "ElementDataFile = LOCAL\na");
  expect_input_error([&] { read_volume(dir + "/sp.mha"); }, {"sp.mha", "spacing of axis 2 is -0.5"});
}

TEST(ReaderHardening, MeshAbsurdCountsFailFast) {
  const std::string dir = test::temp_dir();
  write_bytes(dir + "/huge.off", "OFF\n2000000000 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  expect_input_error([&] { read_mesh(dir + "/huge.off"); }, {"huge.off"});
  std::string stl(80, ' ');
  const std::uint32_t n = 4000000000u;
  stl.append(reinterpret_cast<const char*>(&n), 4);
  stl.append(50, '\0');
  write_bytes(dir + "/huge.stl", stl);
  expect_input_error([&] { read_mesh(dir + "/huge.stl"); }, {"huge.stl"});
  write_bytes(dir + "/huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                                 "property float y\nproperty float z\nelement face 4000000000\n"
                                 "property list uchar int vertex_indices\nend_header\n0123456789ab");
  expect_input_error([&] { read_mesh(dir + "/huge.ply"); }, {"huge.ply"});
}

// CGAL's OFF scanner indexes colour values by an unchecked count and casts
// them unchecked; the OFF check refuses what would reach that, and keeps the
// colour variants CGAL reads correctly.
TEST(ReaderHardening, OffColourRecordsAreCheckedBeforeCgalReadsThem) {
  const std::string dir = test::temp_dir();
  const std::string faces = "3 0 1 2\n3 0 3 1\n3 1 3 2\n3 2 3 0\n";
  const auto off = [&](const std::string& name, const std::string& text) {
    write_bytes(dir + "/" + name, text);
    return dir + "/" + name;
  };
  // Accepted: colour per vertex as RGB integers, RGBA floats or a map index,
  // and CNOFF with normals before the colour; the geometry is read exactly.
  for (const std::string& v : {std::string("0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n0 0 1 9 9 9\n"),
                               std::string("0 0 0 1 0 0 1\n1 0 0 0 .5 0 1\n0 1 0 0 0 1 1\n0 0 1 .2 .2 .2 1\n"),
                               std::string("0 0 0 7\n1 0 0 0\n0 1 0 148\n0 0 1 3\n")}) {
    const Mesh m = read_mesh(off("ok.off", "COFF\n4 4 6\n" + v + faces));
    ASSERT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.faces.size(), 4u);
    EXPECT_EQ(m.vertices[1].x, 1.0);
    EXPECT_EQ(m.vertices[3].z, 1.0);
  }
  const Mesh cn = read_mesh(off("cn.off", "CNOFF\n4 4 6\n0 0 0 0 0 1 255 0 0\n1 0 0 0 0 1 0 255 0\n"
                                          "0 1 0 0 0 1 0 0 255\n0 0 1 0 0 1 9 9 9\n" + faces));
  EXPECT_EQ(cn.vertices[2].y, 1.0);
  EXPECT_EQ(cn.faces.size(), 4u);
  // Refused, naming the record.
  const std::string ok = "1 0 0 0 255 0\n0 1 0 0 0 255\n0 0 1 9 9 9\n";
  expect_input_error([&] { read_mesh(off("a.off", "COFF\n4 4 6\n0 0\n" + ok + faces)); },
                     {"a.off", "vertex 0 has 2 numbers; expected at least 3"});
  expect_input_error([&] { read_mesh(off("b.off", "COFF\n4 4 6\n0 0 0 1 2\n" + ok + faces)); },
                     {"b.off", "vertex 0 has 2 colour values"});
  expect_input_error([&] { read_mesh(off("c.off", "COFF\n4 4 6\n0 0 0 255 0 0\n1 0 0\n0 1 0 0 0 255\n0 0 1 9 9 9\n" + faces)); },
                     {"c.off", "vertex 1 has 0 colour values", "earlier records have colour"});
  expect_input_error([&] { read_mesh(off("d.off", "COFF\n4 4 6\n0 0 0 300 0 0\n" + ok + faces)); },
                     {"d.off", "vertex 0 has colour value 300"});
  expect_input_error([&] { read_mesh(off("e.off", "COFF\n4 4 6\n0 0 0 -5\n1 0 0 0\n0 1 0 0\n0 0 1 0\n" + faces)); },
                     {"e.off", "vertex 0 has colour-map index -5"});
  expect_input_error([&] { read_mesh(off("f.off", "COFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 1 0 0\n3 0 3 1\n3 1 3 2\n3 2 3 0\n")); },
                     {"f.off", "facet 1 has 0 colour values"});
  expect_input_error([&] { read_mesh(off("t.off", "COFF\n4 4 6\n# a comment long enough for the size check\n0 0 0\n1 0 0\n")); },
                     {"t.off", "the file ends after 2 of 4 vertices"});
  expect_input_error([&] { read_mesh(off("u.off", "COFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 9 9 9\n")); },
                     {"u.off", "the file ends after 1 of 4 faces"});
  expect_input_error([&] { read_mesh(off("g.off", "STOFF\n4 4 6\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n0 0 1 1 1\n" + faces)); },
                     {"g.off", "texture coordinates without colours"});
  // Header counts: a negative vertex count after nOFF's dimension (CGAL
  // would take it as a huge size) and an edge count CGAL would double past int are refused.
  const std::string tet_text = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n" + faces;
  expect_input_error([&] { read_mesh(off("nv.off", "nOFF\n3\n-4 4 6\n" + tet_text)); }, {"nv.off", "-4 vertices"});
  expect_input_error([&] { read_mesh(off("ne.off", "OFF\n4 4 2000000000\n" + tet_text)); },
                     {"ne.off", "edge count 2000000000"});
  EXPECT_EQ(read_mesh(off("z.off", "OFF\n0004 0004 0\n" + tet_text)).faces.size(), 4u);
  // Binary OFF: a negative facet vertex count would become a huge size_t.
  std::string bin = "OFF BINARY\n";
  const auto be32 = [&](std::uint32_t u) {
    for (int k = 3; k >= 0; --k) bin += char((u >> (8 * k)) & 0xff);
  };
  be32(3); be32(1); be32(3);
  for (int k = 0; k < 9; ++k) be32(0);  // three vertices, float zero
  be32(0xfffffffdu);                    // facet count -3
  be32(0); be32(1); be32(2);
  expect_input_error([&] { read_mesh(off("h.off", bin)); }, {"h.off", "facet 0 has vertex count -3"});
  // A valid binary tetrahedron reads; cut inside its last face, it is refused
  // (CGAL would resize that face to a count it never read).
  bin = "OFF BINARY\n";
  be32(4); be32(4); be32(6);
  const float xyz[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (float c : xyz) {
    std::uint32_t u;
    std::memcpy(&u, &c, 4);
    be32(u);
  }
  const std::uint32_t faces_v[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  for (const auto& fv : faces_v) {  // each face: its vertex count, then its indices
    be32(3);
    for (const std::uint32_t v : fv) be32(v);
  }
  const Mesh tet = read_mesh(off("tet.off", bin));
  EXPECT_EQ(tet.vertices.size(), 4u);
  EXPECT_EQ(tet.faces.size(), 4u);
  EXPECT_EQ(tet.vertices[3].z, 1.0);
  expect_input_error([&] { read_mesh(off("cut.off", bin.substr(0, bin.size() - 14))); },
                     {"cut.off", "the binary data end inside face 3 of 4"});
}

// --- fuzzer findings ----------------------------------------------------------
// tests/data/regress/<target>-<what>: the input as the fuzz target saw it.
// Each is replayed the way tests/fuzz/fuzz_<target>.cpp feeds it (file name,
// detached data file after the "\n#--data--\n" marker) and must be refused
// with an InputError that names the file.
constexpr const char* kSplit = "\n#--data--\n";

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

void replay(const std::string& target, const std::string& bytes, const std::string& dir) {
  const std::size_t at = bytes.find(kSplit);
  const std::string head = at == std::string::npos ? bytes : bytes.substr(0, at);
  const std::string rest = at == std::string::npos ? std::string() : bytes.substr(at + std::strlen(kSplit));
  const bool gz = bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
                  static_cast<unsigned char>(bytes[1]) == 0x8b;
  std::string path;
  if (target == "nrrd" || target == "metaimage") {
    const bool nrrd = target == "nrrd";
    if (at == std::string::npos) {
      path = dir + (nrrd ? "/fuzz.nrrd" : "/fuzz.mha");
    } else {
      path = dir + (nrrd ? "/fuzz.nhdr" : "/fuzz.mhd");
      write_bytes(dir + "/fuzz.raw", rest);
      write_bytes(dir + (nrrd ? "/fuzz.raw.gz" : "/fuzz.zraw"), rest);
    }
    write_bytes(path, head);
    expect_input_error([&] { read_volume(path); }, {path});
    return;
  }
  if (target == "nifti" || target == "inr" || target == "vdb" || target == "sizing") {
    const std::string ext = target == "nifti" ? (gz ? ".nii.gz" : ".nii")
                            : target == "inr" ? (gz ? ".inr.gz" : ".inr")
                            : target == "vdb" ? ".vdb"
                                              : ".nrrd";
    path = dir + "/fuzz" + ext;
    write_bytes(path, bytes);
    if (target == "sizing")
      expect_input_error([&] { SizingField h(read_volume(path), path); }, {path});
    else
      expect_input_error([&] { read_volume(path); }, {path});
    return;
  }
  const std::string ext = target == "seeds" ? "ply" : target;
  path = dir + "/fuzz." + ext;
  write_bytes(path, bytes);
  expect_input_error([&] { read_mesh(path).validate(path); }, {path});
}

TEST(ReaderHardening, FuzzerFindingsAreRefusedCleanly) {
  const fs::path regress = fs::path(PM_TEST_DATA) / "regress";
  ASSERT_TRUE(fs::is_directory(regress)) << regress;
  int count = 0;
  for (const auto& entry : fs::directory_iterator(regress)) {
    const std::string name = entry.path().filename().string();
    if (name == "README.md") continue;
    // OpenVDB allocates a block size read from the file with new[] before it
    // can know the data are not there: a normal build gets std::bad_alloc,
    // which read_vdb turns into an InputError; AddressSanitizer aborts on the
    // request instead, so the case is only replayed without it.
    if (kAddressSanitizer && name.rfind("vdb-huge", 0) == 0) continue;
    const std::string target = name.substr(0, name.find('-'));
    SCOPED_TRACE(name);
    replay(target, read_bytes(entry.path().string()), test::temp_dir());
    ++count;
  }
  EXPECT_GT(count, 0);
}

}  // namespace
}  // namespace pm

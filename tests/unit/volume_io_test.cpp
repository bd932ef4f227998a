#include "pm/io/volume_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <openvdb/io/File.h>
#include <openvdb/math/Transform.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "pm/base/error.h"
#include "pm/io/gzip.h"
#include "pm/io/inr.h"
#include "pm/io/metaimage.h"
#include "pm/io/nifti.h"
#include "pm/io/nrrd.h"
#include "pm/io/vdb.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

const VoxelType kAllTypes[] = {VoxelType::u8,  VoxelType::i8,  VoxelType::u16, VoxelType::i16, VoxelType::u32,
                               VoxelType::i32, VoxelType::u64, VoxelType::i64, VoxelType::f32, VoxelType::f64};

const Dims kDims{5, 4, 3};  // non-cubic, so swapped axes show

Geometry oblique_geometry() {
  // 30 degrees about z, then 20 degrees about x, times spacings 0.5 0.75 1.25.
  const double a = M_PI / 6, b = M_PI / 9;
  Mat3 rz = Mat3::identity(), rx = Mat3::identity();
  rz[0][0] = std::cos(a); rz[0][1] = -std::sin(a); rz[1][0] = std::sin(a); rz[1][1] = std::cos(a);
  rx[1][1] = std::cos(b); rx[1][2] = -std::sin(b); rx[2][1] = std::sin(b); rx[2][2] = std::cos(b);
  Geometry g;
  g.directions = rx * rz * Mat3::diag(0.5, 0.75, 1.25);
  g.origin = {1.5, -2.25, 3.125};
  return g;
}

Geometry aligned_geometry() { return Geometry::with_spacing(0.5, 0.75, 1.25, {1.5, -2.25, 3.125}); }

// Integer volumes get a byte pattern touching every byte of every voxel (so
// byte order and high bytes are checked); float volumes get varied values.
Volume make_volume(VoxelType t, const Geometry& g) {
  Volume v(t, kDims, g);
  if (is_integer(t)) {
    auto* p = static_cast<unsigned char*>(v.raw());
    for (std::size_t b = 0; b < v.byte_size(); ++b) p[b] = static_cast<unsigned char>((b * 37 + 11) ^ (b >> 3));
  } else {
    for (std::size_t i = 0; i < v.count(); ++i) v.set(i, (double(i) - 29.5) * 0.3712 + 1e-3 * double(i * i));
    v.set(7, 1.0e-30);
    v.set(8, -12345.678);
  }
  return v;
}

void expect_same_voxels(const Volume& a, const Volume& b) {
  ASSERT_EQ(a.type(), b.type()) << voxel_type_name(a.type()) << " vs " << voxel_type_name(b.type());
  ASSERT_TRUE(a.dims() == b.dims()) << a.dims().nx << "x" << a.dims().ny << "x" << a.dims().nz << " vs "
                                    << b.dims().nx << "x" << b.dims().ny << "x" << b.dims().nz;
  ASSERT_EQ(a.byte_size(), b.byte_size());
  EXPECT_EQ(std::memcmp(a.raw(), b.raw(), a.byte_size()), 0) << "voxel values differ";
}

void expect_geometry_near(const Geometry& a, const Geometry& b, double tol) {
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(a.origin[r], b.origin[r], tol) << "origin " << r;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.directions[r][c], b.directions[r][c], tol) << "direction " << r << "," << c;
  }
}

// Write v to dir/name with every voxel type, read it back, compare.
void round_trip_all_types(const std::string& dir, const std::string& name, const Geometry& g, bool compress) {
  for (VoxelType t : kAllTypes) {
    SCOPED_TRACE(std::string(name) + " " + voxel_type_name(t) + (compress ? " compressed" : " raw"));
    const Volume v = make_volume(t, g);
    const std::string path = dir + "/" + voxel_type_name(t) + "_" + name;
    write_volume(v, path, {compress});
    const Volume r = read_volume(path);
    expect_same_voxels(v, r);
    expect_geometry_near(r.geometry(), g, 1e-6);
  }
}

std::size_t files_in(const std::string& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

void truncate_file(const std::string& path, std::size_t drop) {
  fs::resize_file(path, fs::file_size(path) - drop);
}

template <class E>
void expect_throw_with(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning \"" << needle << "\"";
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

// A one-block INRimage header around `body` (KEY=VALUE lines).
std::string inr_header(const std::string& body) {
  std::string h = "#INRIMAGE-4#{\n" + body;
  h.append(252 - h.size(), '\n');
  return h + "##}\n";
}

std::string test_data(const std::string& name) { return std::string(PM_TEST_DATA) + "/" + name; }

// ---------------------------------------------------------------------------
// Round trips

TEST(VolumeIoRoundTrip, NrrdAttachedRawAndGzip) {
  const std::string dir = test::temp_dir();
  round_trip_all_types(dir, "a.nrrd", oblique_geometry(), false);
  round_trip_all_types(dir, "b.nrrd", oblique_geometry(), true);
  EXPECT_EQ(files_in(dir), 20u);  // no temporaries left
  const std::string header = slurp(dir + "/float_b.nrrd").substr(0, 1000);
  EXPECT_NE(header.find("encoding: gzip"), std::string::npos) << header;
  EXPECT_NE(header.find("space directions:"), std::string::npos) << header;
  EXPECT_NE(header.find("kinds: domain domain domain"), std::string::npos) << header;
}

TEST(VolumeIoRoundTrip, NrrdDetachedHeaderNamesTheFinalDataFile) {
  for (bool gz : {false, true}) {
    const std::string dir = test::temp_dir();
    round_trip_all_types(dir, "d.nhdr", oblique_geometry(), gz);
    // One header + one data file per type, nothing else.
    EXPECT_EQ(files_in(dir), 20u);
    const std::string data = std::string("int16_d.") + (gz ? "raw.gz" : "raw");
    EXPECT_TRUE(fs::exists(dir + "/" + data));
    const std::string header = slurp(dir + "/int16_d.nhdr");
    EXPECT_NE(header.find("data file: " + data), std::string::npos) << header;
    EXPECT_EQ(header.find("tmp"), std::string::npos) << header;
    if (!gz) {
      EXPECT_EQ(fs::file_size(dir + "/" + data), kDims.count() * 2);
    }
    // Rewriting replaces the pair consistently.
    Volume v = make_volume(VoxelType::i16, aligned_geometry());
    v.set(0, 4242);
    write_volume(v, dir + "/int16_d.nhdr", {gz});
    EXPECT_EQ(read_volume(dir + "/int16_d.nhdr").get(0), 4242.0);
    EXPECT_EQ(files_in(dir), 20u);
  }
}

TEST(VolumeIoRoundTrip, NrrdDirectWriterPutsDataBesideHeader) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::f32, aligned_geometry());
  write_nrrd(v, dir + "/x.nhdr", true);
  EXPECT_TRUE(fs::exists(dir + "/x.raw.gz"));
  EXPECT_EQ(nhdr_data_path(dir + "/x.nhdr", false), (fs::path(dir) / "x.raw").string());
  expect_same_voxels(v, read_nrrd(dir + "/x.nhdr"));
}

TEST(VolumeIoRoundTrip, MetaImageMhaRawAndCompressed) {
  const std::string dir = test::temp_dir();
  round_trip_all_types(dir, "m.mha", oblique_geometry(), false);
  round_trip_all_types(dir, "z.mha", oblique_geometry(), true);
  EXPECT_EQ(files_in(dir), 20u);
  const std::string text = slurp(dir + "/uint16_z.mha").substr(0, 1000);
  EXPECT_NE(text.find("CompressedData = True"), std::string::npos) << text;
  EXPECT_NE(text.find("ElementType = MET_USHORT"), std::string::npos) << text;
}

TEST(VolumeIoRoundTrip, MetaImageMhdWithZraw) {
  const std::string dir = test::temp_dir();
  round_trip_all_types(dir, "h.mhd", oblique_geometry(), true);
  EXPECT_EQ(files_in(dir), 20u);
  EXPECT_TRUE(fs::exists(dir + "/double_h.zraw"));
  const std::string header = slurp(dir + "/double_h.mhd");
  EXPECT_NE(header.find("ElementDataFile = double_h.zraw"), std::string::npos) << header;
  // Uncompressed .mhd + .raw as well.
  const Volume v = make_volume(VoxelType::i32, aligned_geometry());
  write_volume(v, dir + "/plain.mhd", {false});
  EXPECT_EQ(fs::file_size(dir + "/plain.raw"), v.byte_size());
  expect_same_voxels(v, read_volume(dir + "/plain.mhd"));
}

TEST(VolumeIoRoundTrip, MetaImageTransformMatrixRowsAreAxisDirections) {
  // Axis 0 along world y, axis 1 along world -x, axis 2 along z.
  const std::string dir = test::temp_dir();
  write_text(dir + "/rot.mha",
             "ObjectType = Image\nNDims = 3\nTransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 10 20 30\n"
             "ElementSpacing = 2 3 4\nDimSize = 2 1 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n\x07\x09");
  const Volume v = read_volume(dir + "/rot.mha");
  const Vec3 p = v.geometry().index_to_world({1, 1, 1});
  EXPECT_DOUBLE_EQ(p.x, 10 - 3);
  EXPECT_DOUBLE_EQ(p.y, 20 + 2);
  EXPECT_DOUBLE_EQ(p.z, 30 + 4);
  EXPECT_EQ(v.get(1), 9.0);
}

TEST(VolumeIoRoundTrip, NiftiPlainAndGzip) {
  const std::string dir = test::temp_dir();
  round_trip_all_types(dir, "n.nii", oblique_geometry(), false);
  round_trip_all_types(dir, "n.nii.gz", oblique_geometry(), false);
  EXPECT_EQ(files_in(dir), 20u);
  // .nii.gz really is gzip.
  const std::string head = slurp(dir + "/uint8_n.nii.gz").substr(0, 2);
  EXPECT_EQ(head, std::string("\x1f\x8b"));
}

TEST(VolumeIoRoundTrip, InrPlainAndGzip) {
  const std::string dir = test::temp_dir();
  round_trip_all_types(dir, "i.inr", aligned_geometry(), false);
  round_trip_all_types(dir, "i.inr.gz", aligned_geometry(), false);
  EXPECT_EQ(files_in(dir), 20u);
  const std::string plain = slurp(dir + "/int16_i.inr");
  EXPECT_EQ(plain.size(), 256 + kDims.count() * 2);
  EXPECT_EQ(plain.compare(0, 13, "#INRIMAGE-4#{"), 0);
  EXPECT_EQ(plain.substr(252, 4), "##}\n");
}

TEST(VolumeIoRoundTrip, InrRejectsObliqueGeometryAndLeavesNoFile) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::f32, oblique_geometry());
  expect_throw_with<InputError>([&] { write_volume(v, dir + "/o.inr"); }, "oblique");
  EXPECT_EQ(files_in(dir), 0u);
}

TEST(VolumeIoRoundTrip, VdbFloatKeepsValuesDimsAndGeometry) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::f32, oblique_geometry());
  write_volume(v, dir + "/f.vdb");
  const Volume r = read_volume(dir + "/f.vdb");
  expect_same_voxels(v, r);
  expect_geometry_near(r.geometry(), v.geometry(), 1e-9);

  // A mask whose border is all background keeps its box and its zeros.
  Volume mask(VoxelType::f32, kDims, aligned_geometry());
  mask.set(2, 1, 1, 1.0);
  mask.set(3, 2, 1, 0.5);
  write_volume(mask, dir + "/mask.vdb");
  const Volume m = read_volume(dir + "/mask.vdb");
  expect_same_voxels(mask, m);
  expect_geometry_near(m.geometry(), mask.geometry(), 1e-9);
  EXPECT_EQ(files_in(dir), 2u);
}

TEST(VolumeIoRoundTrip, VdbStoresIntegersAsFloat) {
  const std::string dir = test::temp_dir();
  Volume v(VoxelType::u16, kDims, aligned_geometry());
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i * 1000 % 65536));
  write_volume(v, dir + "/u.vdb");
  const Volume r = read_volume(dir + "/u.vdb");
  EXPECT_EQ(r.type(), VoxelType::f32);
  ASSERT_TRUE(r.dims() == v.dims());
  for (std::size_t i = 0; i < v.count(); ++i) ASSERT_EQ(r.get(i), v.get(i)) << "voxel " << i;
}

TEST(VolumeIoRoundTrip, VdbLevelSetIncludesInactiveVoxelsOfTheBox) {
  ensure_openvdb_initialized();
  const std::string dir = test::temp_dir();
  // Narrow-band sphere, radius 2, voxel 0.25, centre (1,2,3): background 3 voxels = 0.75.
  auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(2.0f, openvdb::Vec3f(1, 2, 3), 0.25f, 3.0f);
  ls->setName("sphere");
  const openvdb::CoordBBox box = ls->evalActiveVoxelBoundingBox();
  openvdb::Int32Grid::Ptr other = openvdb::Int32Grid::create(7);
  other->setName("labels");
  openvdb::io::File(dir + "/ls.vdb").write(openvdb::GridPtrVec{other, ls});

  const Volume v = read_volume(dir + "/ls.vdb");  // skips the int grid
  EXPECT_EQ(v.type(), VoxelType::f32);
  EXPECT_EQ(v.dims().nx, std::size_t(box.dim().x()));
  EXPECT_EQ(v.dims().nz, std::size_t(box.dim().z()));
  EXPECT_NEAR(v.geometry().spacing(0), 0.25, 1e-12);
  const openvdb::Vec3d lo = ls->transform().indexToWorld(box.min());
  EXPECT_NEAR(v.geometry().origin.x, lo.x(), 1e-12);
  EXPECT_NEAR(v.geometry().origin.z, lo.z(), 1e-12);
  // The box corner is far outside the band (inactive) and reads as +background;
  // the voxel nearest the centre is inside (-background); a voxel on the
  // sphere is near 0.
  EXPECT_FLOAT_EQ(static_cast<float>(v.get(0)), 0.75f);
  const Vec3 c = v.geometry().world_to_index({1, 2, 3});
  EXPECT_FLOAT_EQ(static_cast<float>(v.get(std::size_t(std::lround(c.x)), std::size_t(std::lround(c.y)),
                                           std::size_t(std::lround(c.z)))),
                  -0.75f);
  const Vec3 s = v.geometry().world_to_index({3, 2, 3});
  EXPECT_NEAR(v.get(std::size_t(std::lround(s.x)), std::size_t(std::lround(s.y)), std::size_t(std::lround(s.z))), 0.0,
              0.13);
  // A named grid of the wrong type is refused by read_vdb.
  expect_throw_with<InputError>([&] { read_vdb(dir + "/ls.vdb", "labels"); }, "expected a float or double grid");
  expect_throw_with<InputError>([&] { read_vdb(dir + "/ls.vdb", "nope"); }, "no grid named");
}

TEST(VolumeIoRoundTrip, VdbDoubleGridAndNonLinearTransform) {
  ensure_openvdb_initialized();
  const std::string dir = test::temp_dir();
  openvdb::DoubleGrid::Ptr d = openvdb::DoubleGrid::create(0.0);
  d->tree().setValue(openvdb::Coord(1, 2, 3), 0.1);
  d->tree().setValue(openvdb::Coord(3, 2, 3), -1e-300);
  d->setTransform(openvdb::math::Transform::createLinearTransform(2.0));
  openvdb::io::File(dir + "/d.vdb").write(openvdb::GridPtrVec{d});
  const Volume v = read_volume(dir + "/d.vdb");
  EXPECT_EQ(v.type(), VoxelType::f64);
  EXPECT_TRUE((v.dims() == Dims{3, 1, 1}));
  EXPECT_EQ(v.get(0), 0.1);
  EXPECT_EQ(v.get(1), 0.0);
  EXPECT_EQ(v.get(2), -1e-300);
  EXPECT_DOUBLE_EQ(v.geometry().origin.x, 2.0);
  EXPECT_DOUBLE_EQ(v.geometry().origin.z, 6.0);

  openvdb::FloatGrid::Ptr f = openvdb::FloatGrid::create(0.0f);
  f->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
  const openvdb::BBoxd frustum_box(openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(10, 10, 10));
  f->setTransform(openvdb::math::Transform::createFrustumTransform(frustum_box, 0.5, 2.0, 1.0));
  openvdb::io::File(dir + "/frustum.vdb").write(openvdb::GridPtrVec{f});
  expect_throw_with<InputError>([&] { read_volume(dir + "/frustum.vdb"); }, "non-linear transform");

  openvdb::io::File(dir + "/empty.vdb").write(openvdb::GridPtrVec{openvdb::FloatGrid::create(0.0f)});
  expect_throw_with<InputError>([&] { read_volume(dir + "/empty.vdb"); }, "no active voxels");
}

TEST(VolumeIoRoundTrip, NiftiQformAndPixdimFallbacks) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::i16, oblique_geometry());  // rotation x spacing: qform can hold it
  write_volume(v, dir + "/q.nii");
  std::string bytes = slurp(dir + "/q.nii");
  bytes[254] = bytes[255] = 0;  // sform_code = 0: the qform is used
  write_text(dir + "/q.nii", bytes);
  Volume r = read_volume(dir + "/q.nii");
  expect_same_voxels(v, r);
  expect_geometry_near(r.geometry(), v.geometry(), 1e-5);
  bytes[252] = bytes[253] = 0;  // qform_code = 0 too: pixdim only
  write_text(dir + "/q.nii", bytes);
  r = read_volume(dir + "/q.nii");
  expect_geometry_near(r.geometry(), Geometry::with_spacing(0.5, 0.75, 1.25), 1e-6);
}

TEST(VolumeIoRoundTrip, NrrdSpacingsAxisMinsAndCenters) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/c.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nspacings: 2 3 4\n"
                              "axis mins: 10 20 30\ncenters: cell node ???\nencoding: raw\n\nab");
  const Volume v = read_volume(dir + "/c.nrrd");
  // Cell-centred axis 0: the first sample is half a spacing inside the min.
  EXPECT_DOUBLE_EQ(v.geometry().origin.x, 11.0);
  EXPECT_DOUBLE_EQ(v.geometry().origin.y, 20.0);
  EXPECT_DOUBLE_EQ(v.geometry().origin.z, 30.0);
  EXPECT_DOUBLE_EQ(v.geometry().spacing(1), 3.0);
  EXPECT_EQ(v.get(1), double('b'));
  // No spacing at all: 1.
  write_text(dir + "/n.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n\na");
  const Volume n = read_volume(dir + "/n.nrrd");
  for (int a = 0; a < 3; ++a) EXPECT_EQ(n.geometry().spacing(a), 1.0);
  // A named space keeps its coordinates as they are.
  write_text(dir + "/lps.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nspace: left-posterior-superior\n"
                                "sizes: 1 1 1\nspace directions: (-1,0,0) (0,2,0) (0,0,3)\n"
                                "space origin: (5,6,7)\nencoding: raw\n\na");
  const Volume l = read_volume(dir + "/lps.nrrd");
  EXPECT_EQ(l.geometry().directions[0][0], -1.0);
  EXPECT_EQ(l.geometry().origin.z, 7.0);
}

TEST(VolumeIoRoundTrip, KnownExtensions) {
  for (const char* p : {"a.nrrd", "a.NHDR", "a.vdb", "a.mha", "a.mhd", "a.nii", "a.nii.gz", "a.inr", "a.inr.gz"})
    EXPECT_TRUE(is_volume_path(p)) << p;
  for (const char* p : {"a.png", "a.gz", "a.raw", "a", "a.nrrd.gz"}) EXPECT_FALSE(is_volume_path(p)) << p;
}

TEST(VolumeIoRoundTrip, GzipHelpers) {
  std::vector<unsigned char> data(100000);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<unsigned char>(i % 7 == 0 ? i : 0);
  for (bool gz : {false, true}) {
    const auto packed = deflate_buffer(data.data(), data.size(), gz);
    EXPECT_LT(packed.size(), data.size());
    EXPECT_EQ(packed[0] == 0x1f && packed[1] == 0x8b, gz);
    std::vector<unsigned char> out(data.size());
    EXPECT_EQ(inflate_buffer(packed.data(), packed.size(), out.data(), out.size(), "t"), data.size());
    EXPECT_EQ(out, data);
    // A cut stream yields fewer bytes, not an exception.
    EXPECT_LT(inflate_buffer(packed.data(), packed.size() / 2, out.data(), out.size(), "t"), data.size());
  }
  const std::vector<unsigned char> junk(64, 0x55);
  std::vector<unsigned char> out(100);
  EXPECT_THROW(inflate_buffer(junk.data(), junk.size(), out.data(), out.size(), "t"), InputError);
  EXPECT_GE(max_inflated_size(1000), 1000u * 1032u);
}

// ---------------------------------------------------------------------------
// Real files (skipped when ../shared/data is absent)

TEST(VolumeIoRealData, FrogTissueMetaImageZraw) {
  PM_REQUIRE_SHARED(path, "vtk-frogtissue/frogtissue.mhd");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::u8);
  EXPECT_TRUE((v.dims() == Dims{500, 470, 136}));
  EXPECT_DOUBLE_EQ(v.geometry().spacing(0), 1.0);
  EXPECT_DOUBLE_EQ(v.geometry().spacing(1), 1.0);
  EXPECT_DOUBLE_EQ(v.geometry().spacing(2), 1.5);
  EXPECT_TRUE(v.geometry().axis_aligned());
  // PROVENANCE: labels 1..15 are tissues, a few stray labels up to 29;
  // liver (10) has 204672 voxels, skeleton (13) 440722.
  std::size_t liver = 0, skeleton = 0;
  int max_label = 0;
  const auto* p = v.data<std::uint8_t>();
  for (std::size_t i = 0; i < v.count(); ++i) {
    liver += p[i] == 10;
    skeleton += p[i] == 13;
    max_label = std::max<int>(max_label, p[i]);
  }
  EXPECT_EQ(liver, 204672u);
  EXPECT_EQ(skeleton, 440722u);
  EXPECT_EQ(max_label, 29);
}

TEST(VolumeIoRealData, FrogTissueDerivedNrrdHasIdenticalVoxels) {
  PM_REQUIRE_SHARED(mhd, "vtk-frogtissue/frogtissue.mhd");
  PM_REQUIRE_SHARED(nrrd, "vtk-frogtissue/derived/frogtissue.nrrd");
  const Volume a = read_volume(mhd);
  const Volume b = read_volume(nrrd);
  expect_same_voxels(a, b);
  expect_geometry_near(a.geometry(), b.geometry(), 1e-12);
}

TEST(VolumeIoRealData, CgalSkullInr) {
  PM_REQUIRE_SHARED(path, "cgal-skull/skull_2.9.inr");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::f32);
  EXPECT_TRUE((v.dims() == Dims{64, 64, 64}));
  EXPECT_NEAR(v.geometry().spacing(0), 3.94305, 1e-9);
  EXPECT_NEAR(v.geometry().spacing(1), 3.94305, 1e-9);
  EXPECT_NEAR(v.geometry().spacing(2), 3.65079, 1e-9);
  const ValueRange r = value_range(v);
  EXPECT_GE(r.lo, 0.0);
  EXPECT_NEAR(r.hi, 5.43, 0.01);  // PROVENANCE: values 0 .. 5.43
}

TEST(VolumeIoRealData, Ch2betNiftiGz) {
  PM_REQUIRE_SHARED(path, "mricron-ch2bet/ch2bet.nii.gz");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::u8);
  EXPECT_TRUE((v.dims() == Dims{181, 217, 181}));
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.geometry().spacing(a), 1.0, 1e-6);
  EXPECT_GT(value_range(v).hi, 100.0);  // a T1 brain, not an empty volume
}

TEST(VolumeIoRealData, HeadsqQuarterNrrd) {
  PM_REQUIRE_SHARED(path, "vtk-headsq/derived/headsq_quarter.nrrd");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::i16);
  EXPECT_TRUE((v.dims() == Dims{64, 64, 93}));
  EXPECT_NEAR(v.geometry().spacing(0), 3.2, 1e-12);
  EXPECT_NEAR(v.geometry().spacing(1), 3.2, 1e-12);
  EXPECT_NEAR(v.geometry().spacing(2), 1.5, 1e-12);
  const ValueRange r = value_range(v);
  EXPECT_EQ(r.lo, 0.0);  // PROVENANCE: values 0..3926
  EXPECT_EQ(r.hi, 3926.0);
}

TEST(VolumeIoRealData, HeadMrMetaImageRaw) {
  PM_REQUIRE_SHARED(path, "vtk-headmr/HeadMRVolume.mhd");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::u8);
  EXPECT_TRUE((v.dims() == Dims{48, 62, 42}));
  for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(v.geometry().spacing(a), 4.0);
  EXPECT_GT(value_range(v).hi, 0.0);
}

TEST(VolumeIoRealData, Iso2meshBrainNrrd) {
  PM_REQUIRE_SHARED(path, "iso2mesh-head/derived/brain.nrrd");
  const Volume v = read_volume(path);
  EXPECT_EQ(v.type(), VoxelType::u8);
  EXPECT_TRUE((v.dims() == Dims{256, 256, 256}));
  std::size_t set = 0;
  const auto* p = v.data<std::uint8_t>();
  for (std::size_t i = 0; i < v.count(); ++i) set += p[i] != 0;
  EXPECT_EQ(set, 1793271u);  // PROVENANCE: brain.tif 1793271 voxels set
  EXPECT_EQ(value_range(v).hi, 1.0);
}

// ---------------------------------------------------------------------------
// Bad input

TEST(VolumeIoBadInput, MissingFileIsIoError) {
  const std::string dir = test::temp_dir();
  for (const char* name : {"none.nrrd", "none.mha", "none.nii.gz", "none.inr", "none.vdb"})
    expect_throw_with<IoError>([&] { read_volume(dir + "/" + name); }, name);
  // .mhd whose data file is missing
  write_text(dir + "/lost.mhd", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = lost.raw\n");
  expect_throw_with<IoError>([&] { read_volume(dir + "/lost.mhd"); }, "lost.raw");
}

TEST(VolumeIoBadInput, UnknownExtensionIsUsageError) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/x.png", "x");
  expect_throw_with<UsageError>([&] { read_volume(dir + "/x.png"); }, ".nrrd .nhdr");
  expect_throw_with<UsageError>([&] { write_volume(make_volume(VoxelType::u8, aligned_geometry()), dir + "/y.tif"); },
                                ".tif");
  EXPECT_FALSE(fs::exists(dir + "/y.tif"));
}

TEST(VolumeIoBadInput, WritingIntoMissingFolderLeavesNothing) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::f32, aligned_geometry());
  for (const char* name : {"a.nrrd", "a.nhdr", "a.mha", "a.mhd", "a.nii.gz", "a.inr", "a.vdb"})
    expect_throw_with<IoError>([&] { write_volume(v, dir + "/missing/" + name); }, "does not exist");
  EXPECT_FALSE(fs::exists(dir + "/missing"));
  EXPECT_EQ(files_in(dir), 0u);
}

TEST(VolumeIoBadInput, NotThreeDimensionalNrrd) {
  expect_throw_with<InputError>([] { read_volume(test_data("plane2d.nrrd")); }, "expected 3 axes, got 2");
  expect_throw_with<InputError>([] { read_volume(test_data("hyper4d.nrrd")); }, "expected 3 axes, got 4");
  expect_throw_with<InputError>([] { read_volume(test_data("plane2d.nrrd")); }, "plane2d.nrrd");
}

TEST(VolumeIoBadInput, NrrdFixtures) {
  expect_throw_with<InputError>([] { read_volume(test_data("truncated.nrrd")); }, "truncated");
  expect_throw_with<InputError>([] { read_volume(test_data("truncated.nrrd")); }, "256 bytes");
  expect_throw_with<InputError>([] { read_volume(test_data("truncated_header.nrrd")); }, "truncated_header.nrrd");
  expect_throw_with<InputError>([] { read_volume(test_data("zero_axis.nrrd")); }, "zero_axis.nrrd");
  // NaN voxels are the tools' business, not the reader's.
  const Volume nan = read_volume(test_data("nan.nrrd"));
  EXPECT_TRUE(std::isnan(nan.get(2)));
  EXPECT_EQ(nan.get(7), 7.0);
}

TEST(VolumeIoBadInput, TruncatedData) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::f32, aligned_geometry());
  const std::string need = std::to_string(v.byte_size());
  // raw attached NRRD
  write_volume(v, dir + "/t.nrrd", {false});
  truncate_file(dir + "/t.nrrd", 10);
  expect_throw_with<InputError>([&] { read_volume(dir + "/t.nrrd"); }, "truncated: expected " + need + " bytes");
  // gzip NRRD
  write_volume(v, dir + "/tz.nrrd", {true});
  truncate_file(dir + "/tz.nrrd", 30);
  expect_throw_with<InputError>([&] { read_volume(dir + "/tz.nrrd"); }, "truncated");
  // detached raw NRRD: the data file is short
  write_volume(v, dir + "/td.nhdr", {false});
  truncate_file(dir + "/td.raw", 4);
  expect_throw_with<InputError>([&] { read_volume(dir + "/td.nhdr"); }, "truncated");
  // MHA raw and compressed
  write_volume(v, dir + "/t.mha", {false});
  truncate_file(dir + "/t.mha", 1);
  expect_throw_with<InputError>([&] { read_volume(dir + "/t.mha"); }, "truncated: expected " + need + " bytes");
  write_volume(v, dir + "/tz.mha", {true});
  truncate_file(dir + "/tz.mha", 20);
  expect_throw_with<InputError>([&] { read_volume(dir + "/tz.mha"); }, "truncated");
  // MHD + zraw
  write_volume(v, dir + "/tz.mhd", {true});
  truncate_file(dir + "/tz.zraw", 20);
  expect_throw_with<InputError>([&] { read_volume(dir + "/tz.mhd"); }, "truncated");
  // INR plain and gzip
  write_volume(v, dir + "/t.inr");
  truncate_file(dir + "/t.inr", 8);
  expect_throw_with<InputError>([&] { read_volume(dir + "/t.inr"); }, "truncated: expected " + need + " bytes");
  write_volume(v, dir + "/t.inr.gz");
  truncate_file(dir + "/t.inr.gz", 30);
  expect_throw_with<InputError>([&] { read_volume(dir + "/t.inr.gz"); }, "truncated");
  // NIfTI plain
  write_volume(v, dir + "/t.nii");
  truncate_file(dir + "/t.nii", 8);
  expect_throw_with<InputError>([&] { read_volume(dir + "/t.nii"); }, "truncated: expected " + need + " bytes");
}

TEST(VolumeIoBadInput, UnknownMetaImageElementType) {
  expect_throw_with<InputError>([] { read_volume(test_data("unknown_type.mha")); }, "unknown ElementType MET_FOO");
  const std::string dir = test::temp_dir();
  write_text(dir + "/two.mha", "NDims = 2\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\nabcd");
  expect_throw_with<InputError>([&] { read_volume(dir + "/two.mha"); }, "expected 3 axes, got 2");
  write_text(dir + "/rgb.mha",
             "NDims = 3\nDimSize = 1 1 1\nElementNumberOfChannels = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\nabc");
  expect_throw_with<InputError>([&] { read_volume(dir + "/rgb.mha"); }, "ElementNumberOfChannels");
  write_text(dir + "/junk.mha", std::string(5000, 'x'));
  expect_throw_with<InputError>([&] { read_volume(dir + "/junk.mha"); }, "MetaImage header");
}

TEST(VolumeIoBadInput, AbsurdSizesFailBeforeAllocating) {
  const std::string dir = test::temp_dir();
  // 100000^3 voxels: over the 2^34 limit.
  write_text(dir + "/huge.nrrd",
             "NRRD0004\ntype: float\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\n0123456789");
  write_text(dir + "/huge.mha",
             "NDims = 3\nDimSize = 100000 100000 100000\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n0123");
  write_text(dir + "/huge.inr", inr_header("XDIM=100000\nYDIM=100000\nZDIM=100000\nVDIM=1\nTYPE=float\n"
                                           "PIXSIZE=32 bits\nCPU=decm\n") + "0123");
  ASSERT_EQ(fs::file_size(dir + "/huge.inr"), 260u);
  // 2000^3 voxels: under the limit but far more than the file can hold.
  write_text(dir + "/big.nrrd",
             "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2000 2000 2000\nencoding: raw\n\n0123456789");
  write_text(dir + "/bigz.nrrd",
             "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2000 2000 2000\nencoding: gzip\n\n0123456789");
  write_text(dir + "/bigz.mha", "NDims = 3\nDimSize = 2000 2000 2000\nElementType = MET_UCHAR\n"
                                "CompressedData = True\nElementDataFile = LOCAL\n0123456789");
  for (const char* name : {"huge.nrrd", "huge.mha", "huge.inr", "big.nrrd", "bigz.nrrd", "bigz.mha"}) {
    SCOPED_TRACE(name);
    EXPECT_THROW(read_volume(dir + "/" + name), InputError);
  }
  expect_throw_with<InputError>([&] { read_volume(dir + "/huge.mha"); }, "2^34");
  expect_throw_with<InputError>([&] { read_volume(dir + "/big.nrrd"); }, "truncated: expected 8000000000 bytes");
}

TEST(VolumeIoBadInput, ZeroAndNegativeSpacing) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/s.nrrd",
             "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 0\nencoding: raw\n\n01234567");
  // Teem itself rejects a zero in "spacings"; its reason is passed on.
  expect_throw_with<InputError>([&] { read_volume(dir + "/s.nrrd"); }, "axis 2 spacing (0) invalid");
  write_text(dir + "/n.nrrd",
             "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspacings: 1 -2 1\nencoding: raw\n\n01234567");
  expect_throw_with<InputError>([&] { read_volume(dir + "/n.nrrd"); }, "spacing of axis 1 is -2");
  write_text(dir + "/d.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nspace dimension: 3\n"
                              "space directions: (1,0,0) (0,0,0) (0,0,1)\nencoding: raw\n\n01234567");
  expect_throw_with<InputError>([&] { read_volume(dir + "/d.nrrd"); }, "spacing of axis 1 is 0");
  write_text(dir + "/s.mha",
             "NDims = 3\nDimSize = 2 1 1\nElementSpacing = 1 0 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\nab");
  expect_throw_with<InputError>([&] { read_volume(dir + "/s.mha"); }, "spacing of axis 1 is 0");
  write_text(dir + "/s.inr", inr_header("XDIM=2\nYDIM=1\nZDIM=1\nVDIM=1\nTYPE=unsigned fixed\n"
                                        "PIXSIZE=8 bits\nVX=1\nVY=1\nVZ=0\n") + "ab");
  ASSERT_EQ(fs::file_size(dir + "/s.inr"), 258u);
  expect_throw_with<InputError>([&] { read_volume(dir + "/s.inr"); }, "spacing of axis 2 is 0");
  write_text(dir + "/z.mha", "NDims = 3\nDimSize = 2 0 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n");
  expect_throw_with<InputError>([&] { read_volume(dir + "/z.mha"); }, "axis 1 has size 0");
}

TEST(VolumeIoBadInput, CorruptFiles) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/bad.vdb", "not a vdb file at all");
  expect_throw_with<InputError>([&] { read_volume(dir + "/bad.vdb"); }, "bad.vdb");
  write_text(dir + "/bad.nii", std::string(400, '\0'));
  expect_throw_with<InputError>([&] { read_volume(dir + "/bad.nii"); }, "bad.nii");
  std::string nii2(600, '\0');
  nii2[0] = char(540 & 0xff);
  nii2[1] = char(540 >> 8);
  write_text(dir + "/two.nii", nii2);
  expect_throw_with<InputError>([&] { read_volume(dir + "/two.nii"); }, "NIfTI-2");
  write_text(dir + "/bad.inr", "#INRIMAGE-5#{\n");
  expect_throw_with<InputError>([&] { read_volume(dir + "/bad.inr"); }, "#INRIMAGE-4#{");
  write_text(dir + "/bad.nrrd", "this is not a nrrd\n");
  expect_throw_with<InputError>([&] { read_volume(dir + "/bad.nrrd"); }, "bad.nrrd");
}

}  // namespace
}  // namespace pm

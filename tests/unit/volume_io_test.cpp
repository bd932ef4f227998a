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

TEST(VolumeIoRoundTrip, NrrdKeepsKeyValuePairs) {
  // tighten --outside-band says in the file how far its distances are exact;
  // the NRRD writer and reader keep such keys (attached and detached headers).
  const std::string dir = test::temp_dir();
  Volume v(VoxelType::f32, Dims{3, 4, 5}, oblique_geometry());
  v.set_key(kExactPositiveKey, "24.738633753705962");
  v.set_key("pm_note", "two words");
  for (const char* name : {"k.nrrd", "k.nhdr"}) {
    write_volume(v, dir + "/" + name);
    const Volume r = read_volume(dir + "/" + name);
    EXPECT_EQ(r.keys(), v.keys()) << name;
    EXPECT_EQ(exact_within(r, true, name), 24.738633753705962) << name;
    EXPECT_TRUE(std::isinf(exact_within(r, false, name))) << name;  // no key: exact everywhere
  }
  EXPECT_NE(slurp(dir + "/k.nrrd").substr(0, 800).find("pm_exact_positive:=24.738633753705962"), std::string::npos);
  // A value that is not a distance is refused, naming the key and the value.
  Volume bad(VoxelType::f32, Dims{2, 2, 2});
  bad.set_key(kExactNegativeKey, "-1");
  try {
    exact_within(bad, false, "b.nrrd");
    FAIL() << "a negative band was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.nrrd: key pm_exact_negative is \"-1\"; expected a distance > 0"),
              std::string::npos)
        << e.what();
  }
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

TEST(VolumeIoRoundTrip, VdbStoresLabelsAsIntegerGridsOfTheSameType) {
  openvdb::initialize();
  const std::string dir = test::temp_dir();
  // Every integer type comes back with its type and values (the byte pattern
  // of make_volume reaches each type's extremes), in an int32 grid or, when a
  // value needs it, an int64 grid, with the metadata that says so.
  for (VoxelType t : kAllTypes) {
    if (!is_integer(t)) continue;
    SCOPED_TRACE(voxel_type_name(t));
    Volume v = make_volume(t, oblique_geometry());
    if (t == VoxelType::u64) {  // VDB's widest integer grid is int64: stay below 2^63
      auto* p = v.data<std::uint64_t>();
      for (std::size_t i = 0; i < v.count(); ++i) p[i] >>= 1;
    }
    const std::string path = dir + "/" + voxel_type_name(t) + ".vdb";
    write_volume(v, path);
    const Volume r = read_volume(path);
    expect_same_voxels(v, r);
    expect_geometry_near(r.geometry(), v.geometry(), 1e-9);
    openvdb::io::File f(path);
    f.open();
    const openvdb::GridBase::Ptr g = f.readGrid("field");
    const bool wide = t == VoxelType::u32 || t == VoxelType::u64 || t == VoxelType::i64;
    EXPECT_EQ(g->type(), wide ? openvdb::Int64Grid::gridType() : openvdb::Int32Grid::gridType());
    EXPECT_EQ(g->metaValue<std::string>("pm_voxel_type"), voxel_type_name(t));
    EXPECT_TRUE(g->metaValue<bool>("pm_labels"));
    EXPECT_EQ(g->metaValue<std::string>("pm_world_frame"), "LPS");
  }
  // A label map of small labels is an int32 grid; float stays a float grid.
  Volume labels(VoxelType::u8, kDims, aligned_geometry());
  labels.set(2, 1, 1, 3);
  labels.set(4, 3, 2, 250);
  write_volume(labels, dir + "/labels.vdb");
  EXPECT_EQ(read_volume(dir + "/labels.vdb").type(), VoxelType::u8);
  openvdb::io::File lf(dir + "/labels.vdb");
  lf.open();
  EXPECT_EQ(lf.readGrid("field")->type(), openvdb::Int32Grid::gridType());
  write_volume(make_volume(VoxelType::f32, aligned_geometry()), dir + "/f.vdb");
  openvdb::io::File ff(dir + "/f.vdb");
  ff.open();
  EXPECT_EQ(ff.readGrid("field")->type(), openvdb::FloatGrid::gridType());
  EXPECT_EQ(read_volume(dir + "/f.vdb").type(), VoxelType::f32);
  // uint64 values of 2^63 and more do not fit any VDB grid: refused, no file.
  Volume huge(VoxelType::u64, kDims, aligned_geometry());
  huge.data<std::uint64_t>()[5] = std::uint64_t(1) << 63;
  expect_throw_with<InputError>([&] { write_volume(huge, dir + "/huge.vdb"); }, "below 2^63");
  EXPECT_FALSE(fs::exists(dir + "/huge.vdb"));
}

TEST(VolumeIoRoundTrip, VdbIntegerGridsFromElsewhereAndBadMetadata) {
  openvdb::initialize();
  const std::string dir = test::temp_dir();
  // An int32 grid without our metadata reads as int32, taken as LPS.
  openvdb::Int32Grid::Ptr g = openvdb::Int32Grid::create(0);
  g->tree().setValue(openvdb::Coord(0, 0, 0), 5);
  g->tree().setValue(openvdb::Coord(2, 0, 0), -7);
  g->setName("seg");
  openvdb::io::File(dir + "/plain.vdb").write(openvdb::GridPtrVec{g});
  const Volume v = read_volume(dir + "/plain.vdb");
  EXPECT_EQ(v.type(), VoxelType::i32);
  EXPECT_TRUE((v.dims() == Dims{3, 1, 1}));
  EXPECT_EQ(v.get(0), 5.0);
  EXPECT_EQ(v.get(2), -7.0);
  EXPECT_FALSE(v.frame_source().anatomical);
  EXPECT_NE(v.frame_source().note.find("taken as LPS"), std::string::npos);
  // Values that do not fit the type the metadata names.
  g->insertMeta("pm_voxel_type", openvdb::StringMetadata("uint8"));
  openvdb::io::File(dir + "/lie.vdb").write(openvdb::GridPtrVec{g});
  expect_throw_with<InputError>([&] { read_volume(dir + "/lie.vdb"); }, "holds -7, outside its pm_voxel_type uint8");
  g->insertMeta("pm_voxel_type", openvdb::StringMetadata("float"));
  openvdb::io::File(dir + "/float.vdb").write(openvdb::GridPtrVec{g});
  expect_throw_with<InputError>([&] { read_volume(dir + "/float.vdb"); }, "expected an integer voxel type");
  // A grid in RAS is taken to LPS; an unknown frame is refused.
  g->insertMeta("pm_voxel_type", openvdb::StringMetadata("int16"));
  g->insertMeta("pm_world_frame", openvdb::StringMetadata("RAS"));
  g->setTransform(openvdb::math::Transform::createLinearTransform(2.0));
  openvdb::io::File(dir + "/ras.vdb").write(openvdb::GridPtrVec{g});
  const Volume r = read_volume(dir + "/ras.vdb");
  EXPECT_EQ(r.type(), VoxelType::i16);
  const Vec3 p = r.geometry().index_to_world({2, 0, 0});  // RAS (4, 0, 0)
  EXPECT_DOUBLE_EQ(p.x, -4.0);
  EXPECT_DOUBLE_EQ(r.geometry().directions[1][1], -2.0);
  EXPECT_DOUBLE_EQ(r.geometry().directions[2][2], 2.0);
  g->insertMeta("pm_world_frame", openvdb::StringMetadata("RIP"));
  openvdb::io::File(dir + "/rip.vdb").write(openvdb::GridPtrVec{g});
  expect_throw_with<InputError>([&] { read_volume(dir + "/rip.vdb"); }, "pm_world_frame \"RIP\"; expected LPS or RAS");
}

TEST(VolumeIoRoundTrip, VdbLevelSetIncludesInactiveVoxelsOfTheBox) {
  openvdb::initialize();
  const std::string dir = test::temp_dir();
  // Narrow-band sphere, radius 2, voxel 0.25, centre (1,2,3): background 3 voxels = 0.75.
  auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(2.0f, openvdb::Vec3f(1, 2, 3), 0.25f, 3.0f);
  ls->setName("sphere");
  const openvdb::CoordBBox box = ls->evalActiveVoxelBoundingBox();
  openvdb::Int32Grid::Ptr other = openvdb::Int32Grid::create(7);
  other->setName("labels");
  openvdb::io::File(dir + "/ls.vdb").write(openvdb::GridPtrVec{other, ls});

  const Volume v = read_volume(dir + "/ls.vdb");  // skips the empty int grid
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
  // A named grid of a type we do not read is refused by read_vdb; a named
  // empty grid is reported as empty.
  openvdb::Vec3SGrid::Ptr vectors = openvdb::Vec3SGrid::create();
  vectors->setName("vectors");
  openvdb::io::File(dir + "/vec.vdb").write(openvdb::GridPtrVec{vectors, ls});
  expect_throw_with<InputError>([&] { read_vdb(dir + "/vec.vdb", "vectors"); },
                                "expected a float, double, int32 or int64 grid");
  expect_throw_with<InputError>([&] { read_vdb(dir + "/ls.vdb", "labels"); }, "no active voxels");
  expect_throw_with<InputError>([&] { read_vdb(dir + "/ls.vdb", "nope"); }, "no grid named");
}

TEST(VolumeIoRoundTrip, VdbDoubleGridAndNonLinearTransform) {
  openvdb::initialize();
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
  // left-posterior-superior is libcore's own frame: kept as it is.
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
// World frame: every reader converts into LPS, every writer out of it
// (pm/base/volume.h).

// A one-voxel-per-axis-step NRRD text header + data in `space`.
std::string nrrd_in_space(const std::string& space_line, const std::string& dirs, const std::string& origin) {
  return "NRRD0004\ntype: uint8\ndimension: 3\n" + space_line + "sizes: 2 1 1\nspace directions: " + dirs +
         "\nspace origin: " + origin + "\nencoding: raw\n\nab";
}

TEST(VolumeIoFrame, NrrdSpacesAreConvertedToLps) {
  const std::string dir = test::temp_dir();
  struct Case {
    const char* space;
    Vec3 signs;
    bool anatomical;
  };
  const Case cases[] = {{"right-anterior-superior", {-1, -1, 1}, true}, {"RAS", {-1, -1, 1}, true},
                        {"left-anterior-superior", {1, -1, 1}, true},   {"left-posterior-superior", {1, 1, 1}, true},
                        {"scanner-xyz", {1, 1, 1}, true},               {"3D-right-handed", {1, 1, 1}, false},
                        {"3D-left-handed", {1, 1, 1}, false}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.space);
    write_text(dir + "/s.nrrd", nrrd_in_space(std::string("space: ") + c.space + "\n", "(0.5,0.25,0) (0,2,0) (0,0,3)",
                                              "(10,20,30)"));
    const Volume v = read_volume(dir + "/s.nrrd");
    // Voxel (1,0,0) sits at (10.5, 20.25, 30) in the file's space.
    const Vec3 p = v.geometry().index_to_world({1, 0, 0});
    EXPECT_DOUBLE_EQ(p.x, c.signs.x * 10.5);
    EXPECT_DOUBLE_EQ(p.y, c.signs.y * 20.25);
    EXPECT_DOUBLE_EQ(p.z, c.signs.z * 30);
    EXPECT_EQ(v.frame_source().format, "NRRD");
    EXPECT_EQ(v.frame_source().anatomical, c.anatomical);
    EXPECT_EQ(v.frame_source().space.empty(), false);
  }
  // The "-time" spaces: the fourth component of each direction must be 0.
  write_text(dir + "/t.nrrd", nrrd_in_space("space: right-anterior-superior-time\n",
                                            "(1,0,0,0) (0,1,0,0) (0,0,1,0)", "(10,20,30,5)"));
  const Volume t = read_volume(dir + "/t.nrrd");
  EXPECT_DOUBLE_EQ(t.geometry().origin.x, -10);
  EXPECT_DOUBLE_EQ(t.geometry().directions[1][1], -1);
  write_text(dir + "/tt.nrrd", nrrd_in_space("space: right-anterior-superior-time\n",
                                             "(1,0,0,0) (0,1,0,0.5) (0,0,1,0)", "(10,20,30,5)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/tt.nrrd"); }, "axis 1 has time component 0.5");
  // No named space: kept as given, and said so.
  write_text(dir + "/n.nrrd", nrrd_in_space("space dimension: 3\n", "(1,0,0) (0,1,0) (0,0,1)", "(10,20,30)"));
  const Volume n = read_volume(dir + "/n.nrrd");
  EXPECT_DOUBLE_EQ(n.geometry().origin.x, 10);
  EXPECT_FALSE(n.frame_source().anatomical);
}

TEST(VolumeIoFrame, TwoNrrdsDifferingOnlyInSpaceDiffer) {
  const std::string dir = test::temp_dir();
  write_text(dir + "/lps.nrrd", nrrd_in_space("space: left-posterior-superior\n", "(1,0,0) (0,1,0) (0,0,1)", "(10,20,30)"));
  write_text(dir + "/ras.nrrd", nrrd_in_space("space: right-anterior-superior\n", "(1,0,0) (0,1,0) (0,0,1)", "(10,20,30)"));
  const Geometry a = read_volume(dir + "/lps.nrrd").geometry(), b = read_volume(dir + "/ras.nrrd").geometry();
  EXPECT_DOUBLE_EQ(a.origin.x, 10);
  EXPECT_DOUBLE_EQ(b.origin.x, -10);
  EXPECT_DOUBLE_EQ(b.origin.y, -20);
  EXPECT_DOUBLE_EQ(b.origin.z, 30);
  EXPECT_DOUBLE_EQ(b.directions[0][0], -1);
  // Written back, both say LPS with the converted numbers.
  write_volume(read_volume(dir + "/ras.nrrd"), dir + "/out.nrrd", {false});
  const std::string h = slurp(dir + "/out.nrrd").substr(0, 400);
  EXPECT_NE(h.find("space: left-posterior-superior"), std::string::npos) << h;
  EXPECT_NE(h.find("space origin: (-10,-20,30)"), std::string::npos) << h;
  EXPECT_NE(h.find("space directions: (-1,0,0) (0,-1,0) (0,0,1)"), std::string::npos) << h;
}

TEST(VolumeIoFrame, NrrdSpacesWeCannotMapAreErrors) {
  const std::string dir = test::temp_dir();
  // A 2-D space for a 3-D volume.
  write_text(dir + "/2d.nrrd", nrrd_in_space("space: right-up\n", "(1,0) (0,1) (1,1)", "(1,2)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/2d.nrrd"); }, "space \"right-up\" is 2-D; expected a 3-D space");
  // A space Teem does not know: Teem's reason names it.
  write_text(dir + "/odd.nrrd", nrrd_in_space("space: upside-down\n", "(1,0,0) (0,1,0) (0,0,1)", "(1,2,3)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/odd.nrrd"); }, "upside-down");
  // space and space directions of different dimensions.
  write_text(dir + "/mix.nrrd", nrrd_in_space("space: left-posterior-superior\n", "(1,0) (0,1) (0,0)", "(1,2,3)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/mix.nrrd"); }, "mix.nrrd");
  write_text(dir + "/mix4.nrrd",
             nrrd_in_space("space: left-posterior-superior\n", "(1,0,0,0) (0,1,0,0) (0,0,1,0)", "(1,2,3)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/mix4.nrrd"); }, "mix4.nrrd");
  // "space" and "space dimension" that disagree.
  write_text(dir + "/dim.nrrd", nrrd_in_space("space: left-posterior-superior\nspace dimension: 4\n",
                                              "(1,0,0,0) (0,1,0,0) (0,0,1,0)", "(1,2,3,0)"));
  expect_throw_with<InputError>([&] { read_volume(dir + "/dim.nrrd"); }, "dim.nrrd");
}

// Header fields of a NIfTI-1 file we wrote (.nii, little endian).
struct NiftiFields {
  float srow[3][4];
  float qoffset[3];
  std::int16_t qform_code, sform_code;
  unsigned char xyzt_units;
};
NiftiFields nifti_fields(const std::string& bytes) {
  NiftiFields f;
  std::memcpy(f.srow, bytes.data() + 280, sizeof f.srow);
  std::memcpy(f.qoffset, bytes.data() + 268, sizeof f.qoffset);
  std::memcpy(&f.qform_code, bytes.data() + 252, 2);
  std::memcpy(&f.sform_code, bytes.data() + 254, 2);
  f.xyzt_units = static_cast<unsigned char>(bytes[123]);
  return f;
}

TEST(VolumeIoFrame, NiftiIsWrittenAndReadInRas) {
  const std::string dir = test::temp_dir();
  // LPS origin (10, 20, 30), axis 0 along LPS +x: in RAS (-10, -20, 30), axis 0 along -x.
  Volume v = make_volume(VoxelType::i16, Geometry::with_spacing(0.5, 0.75, 1.25, {10, 20, 30}));
  write_volume(v, dir + "/a.nii");
  const NiftiFields f = nifti_fields(slurp(dir + "/a.nii"));
  EXPECT_FLOAT_EQ(f.srow[0][3], -10);
  EXPECT_FLOAT_EQ(f.srow[1][3], -20);
  EXPECT_FLOAT_EQ(f.srow[2][3], 30);
  EXPECT_FLOAT_EQ(f.srow[0][0], -0.5);
  EXPECT_FLOAT_EQ(f.srow[1][1], -0.75);
  EXPECT_FLOAT_EQ(f.srow[2][2], 1.25);
  EXPECT_FLOAT_EQ(f.qoffset[0], -10);
  EXPECT_FLOAT_EQ(f.qoffset[1], -20);
  EXPECT_FLOAT_EQ(f.qoffset[2], 30);
  EXPECT_EQ(f.sform_code, 1);
  EXPECT_EQ(f.qform_code, 1);
  EXPECT_EQ(f.xyzt_units & 7, 2);  // NIFTI_UNITS_MM
  const Volume r = read_volume(dir + "/a.nii");
  expect_geometry_near(r.geometry(), v.geometry(), 1e-6);
  EXPECT_TRUE(r.frame_source().anatomical);
  EXPECT_NE(r.frame_source().space.find("RAS (sform, scanner_anat, mm)"), std::string::npos) << r.frame_source().space;
}

TEST(VolumeIoFrame, NiftiUnitsAreTakenToMillimetres) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::u8, oblique_geometry());
  write_volume(v, dir + "/mm.nii");
  std::string bytes = slurp(dir + "/mm.nii");
  const struct {
    unsigned char code;
    double scale;
    const char* name;
  } units[] = {{1, 1000.0, "m"}, {3, 0.001, "um"}, {0, 1.0, "unknown units, taken as mm"}};
  for (const auto& u : units) {
    SCOPED_TRACE(u.name);
    bytes[123] = static_cast<char>(u.code | 8);  // + seconds for time, which must not matter
    write_text(dir + "/u.nii", bytes);
    const Volume r = read_volume(dir + "/u.nii");
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(r.geometry().spacing(a), u.scale * v.geometry().spacing(a), 1e-6 * u.scale);
    EXPECT_NEAR(r.geometry().origin.y, u.scale * v.geometry().origin.y, 1e-6 * u.scale);
    EXPECT_NE(r.frame_source().space.find(u.name), std::string::npos) << r.frame_source().space;
  }
}

TEST(VolumeIoFrame, NiftiWithoutQformOrSformIsInVoxelUnitsWithAWarning) {
  const std::string dir = test::temp_dir();
  const Volume v = make_volume(VoxelType::u8, Geometry::with_spacing(2, 3, 4, {10, 20, 30}));
  write_volume(v, dir + "/a.nii");
  std::string bytes = slurp(dir + "/a.nii");
  bytes[252] = bytes[253] = bytes[254] = bytes[255] = 0;
  write_text(dir + "/a.nii", bytes);
  testing::internal::CaptureStderr();
  const Volume r = read_volume(dir + "/a.nii");
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("qform_code and sform_code are both 0"), std::string::npos) << err;
  EXPECT_NE(err.find("a.nii"), std::string::npos) << err;
  expect_geometry_near(r.geometry(), Geometry::with_spacing(2, 3, 4), 1e-9);
  EXPECT_FALSE(r.frame_source().anatomical);
  expect_same_voxels(v, r);
}

TEST(VolumeIoFrame, MetaImageAnatomicalOrientation) {
  const std::string dir = test::temp_dir();
  // Without a TransformMatrix the code gives the axes: RAI = +x +y +z, LPS =
  // -x -y -z, PIR: axis 0 -y, axis 1 +z, axis 2 +x.
  const struct {
    const char* code;
    Vec3 dirs[3];
  } cases[] = {{"RAI", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
               {"LPS", {{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}}},
               {"PIR", {{0, -1, 0}, {0, 0, 1}, {1, 0, 0}}}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.code);
    write_text(dir + "/o.mha", std::string("NDims = 3\nOffset = 1 2 3\nAnatomicalOrientation = ") + c.code +
                                   "\nElementSpacing = 2 3 4\nDimSize = 1 1 1\nElementType = MET_UCHAR\n"
                                   "ElementDataFile = LOCAL\na");
    const Volume v = read_volume(dir + "/o.mha");
    const double sp[3] = {2, 3, 4};
    for (int a = 0; a < 3; ++a)
      for (int r = 0; r < 3; ++r) EXPECT_EQ(v.geometry().directions[r][a], sp[a] * c.dirs[a][r]) << a << "," << r;
    EXPECT_EQ(v.frame_source().space, std::string("LPS (AnatomicalOrientation ") + c.code + ")");
    // Written back: the same code, and the matrix.
    write_volume(v, dir + "/back.mha", {false});
    const std::string h = slurp(dir + "/back.mha").substr(0, 500);
    EXPECT_NE(h.find(std::string("AnatomicalOrientation = ") + c.code), std::string::npos) << h;
  }
  // The writer's code for an oblique volume: the closest axes.
  write_volume(make_volume(VoxelType::u8, oblique_geometry()), dir + "/obl.mha", {false});
  EXPECT_NE(slurp(dir + "/obl.mha").find("AnatomicalOrientation = RAI"), std::string::npos);
  // A TransformMatrix wins over a code that disagrees, with a warning.
  write_text(dir + "/both.mha", "NDims = 3\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nAnatomicalOrientation = LPS\n"
                                "DimSize = 1 1 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\na");
  testing::internal::CaptureStderr();
  const Volume b = read_volume(dir + "/both.mha");
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(b.geometry().directions[0][0], 1.0);
  EXPECT_NE(err.find("AnatomicalOrientation LPS disagrees with the TransformMatrix (RAI)"), std::string::npos) << err;
  // An unknown code ("???", as some writers put) is ignored.
  write_text(dir + "/q.mha", "NDims = 3\nAnatomicalOrientation = ???\nDimSize = 1 1 1\nElementType = MET_UCHAR\n"
                             "ElementDataFile = LOCAL\na");
  EXPECT_EQ(read_volume(dir + "/q.mha").geometry().directions[1][1], 1.0);
}

TEST(VolumeIoFrame, InrStoresFlippedAxesReversed) {
  const std::string dir = test::temp_dir();
  // A RAS NIfTI's usual geometry in LPS: x and y flipped.
  Geometry g = Geometry::with_spacing(0.5, 0.75, 1.25, {10, 20, 30});
  g.directions[0][0] = -0.5;
  g.directions[1][1] = -0.75;
  const Volume v = make_volume(VoxelType::f32, g);
  write_volume(v, dir + "/f.inr");
  const Volume r = read_volume(dir + "/f.inr");
  EXPECT_TRUE(r.geometry().axis_aligned());
  EXPECT_GT(r.geometry().directions[0][0], 0);
  EXPECT_GT(r.geometry().directions[1][1], 0);
  EXPECT_FALSE(r.frame_source().anatomical);
  EXPECT_NE(r.frame_source().note.find("INR has no world frame"), std::string::npos);
  // Every voxel keeps its world position and value.
  ASSERT_TRUE(r.dims() == v.dims());
  for (std::size_t k = 0; k < kDims.nz; ++k)
    for (std::size_t j = 0; j < kDims.ny; ++j)
      for (std::size_t i = 0; i < kDims.nx; ++i) {
        const Vec3 p = v.geometry().index_to_world(Vec3(double(i), double(j), double(k)));
        const Vec3 q = r.geometry().world_to_index(p);
        const std::size_t ri = std::size_t(std::lround(q.x)), rj = std::size_t(std::lround(q.y)),
                          rk = std::size_t(std::lround(q.z));
        ASSERT_NEAR(q.x, double(ri), 1e-9);
        ASSERT_NEAR(q.y, double(rj), 1e-9);
        ASSERT_NEAR(q.z, double(rk), 1e-9);
        ASSERT_EQ(r.get(ri, rj, rk), v.get(i, j, k)) << i << " " << j << " " << k;
      }
}

// Every pair of formats keeps the anatomy: the volume written in format A,
// read, written in format B and read again has the same voxel at the same
// LPS point (the formats' own frames are checked by the tests above and by
// nibabel in tests/cli/frames_test.py).
TEST(VolumeIoFrame, EveryFormatPairKeepsTheAnatomy) {
  const std::string dir = test::temp_dir();
  Geometry flipped = Geometry::with_spacing(0.5, 0.75, 1.25, {10, 20, 30});
  flipped.directions[0][0] = -0.5;
  flipped.directions[2][2] = -1.25;
  const struct {
    const char* name;
    Geometry g;
    bool inr;  // INR holds axis-aligned volumes only
  } geoms[] = {{"oblique", oblique_geometry(), false}, {"flipped", flipped, true},
               {"anisotropic", aligned_geometry(), true}};
  const char* exts[] = {".nrrd", ".nhdr", ".mha", ".mhd", ".nii", ".nii.gz", ".inr", ".vdb"};
  for (const auto& geo : geoms) {
    Volume v(VoxelType::i16, kDims, geo.g);
    for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i) + 1);  // every voxel distinct
    for (const char* a : exts) {
      for (const char* b : exts) {
        if (!geo.inr && (std::string(a) == ".inr" || std::string(b) == ".inr")) continue;
        SCOPED_TRACE(std::string(geo.name) + " " + a + " -> " + b);
        write_volume(v, dir + "/a" + a);
        write_volume(read_volume(dir + "/a" + a), dir + "/b" + b);
        const Volume r = read_volume(dir + "/b" + b);
        ASSERT_EQ(r.count(), v.count());
        for (std::size_t k = 0; k < kDims.nz; ++k)
          for (std::size_t j = 0; j < kDims.ny; ++j)
            for (std::size_t i = 0; i < kDims.nx; ++i) {
              const Vec3 q = v.geometry().world_to_index(r.geometry().index_to_world(Vec3(double(i), double(j), double(k))));
              // NIfTI stores float32: 1e-6 relative of coordinates near 30.
              const long si = std::lround(q.x), sj = std::lround(q.y), sk = std::lround(q.z);
              ASSERT_NEAR(q.x, double(si), 1e-4);
              ASSERT_NEAR(q.y, double(sj), 1e-4);
              ASSERT_NEAR(q.z, double(sk), 1e-4);
              ASSERT_TRUE(si >= 0 && sj >= 0 && sk >= 0 && std::size_t(si) < kDims.nx && std::size_t(sj) < kDims.ny &&
                          std::size_t(sk) < kDims.nz)
                  << "voxel " << i << " " << j << " " << k << " maps outside the source: " << q.x << " " << q.y << " "
                  << q.z;
              ASSERT_EQ(r.get(i, j, k), v.get(std::size_t(si), std::size_t(sj), std::size_t(sk)));
            }
      }
    }
  }
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

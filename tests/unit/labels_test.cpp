#include "pm/volume/labels.h"

#include <gtest/gtest.h>

#include "pm/base/error.h"

namespace pm {
namespace {

Volume small_labels() {
  Volume v(VoxelType::u8, Dims{4, 3, 2});
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i % 5));  // labels 0..4
  return v;
}

TEST(Labels, ParseMergeSpec) {
  const auto r = parse_merge_spec("1,2:1 3-4:2;7:0");
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0].from, (std::vector<std::int64_t>{1, 2}));
  EXPECT_EQ(r[0].to, 1);
  EXPECT_EQ(r[1].from, (std::vector<std::int64_t>{3, 4}));
  EXPECT_EQ(r[2].to, 0);
  EXPECT_THROW(parse_merge_spec("1,2"), UsageError);
  EXPECT_THROW(parse_merge_spec("1:2 1:3"), UsageError);
  EXPECT_THROW(parse_merge_spec("a:2"), UsageError);
  EXPECT_THROW(parse_label_list(""), UsageError);
}

TEST(Labels, CountsMaskMerge) {
  const Volume v = small_labels();
  const auto c = label_counts(v);
  ASSERT_EQ(c.size(), 5u);
  std::size_t total = 0;
  for (const auto& [l, n] : c) total += n;
  EXPECT_EQ(total, v.count());
  EXPECT_EQ(c.at(0), 5u);  // 24 voxels, i % 5 == 0 for i = 0,5,10,15,20

  const Volume m = label_mask(v, {1, 3});
  EXPECT_EQ(m.type(), VoxelType::u8);
  std::size_t ones = 0;
  for (std::size_t i = 0; i < m.count(); ++i) ones += m.get(i) == 1.0;
  EXPECT_EQ(ones, c.at(1) + c.at(3));
  EXPECT_THROW(label_mask(v, {9}), InputError);

  const Volume g = merge_labels(v, parse_merge_spec("1,2:1 3,4:300"));
  EXPECT_EQ(g.type(), VoxelType::i32);  // 300 does not fit uint8
  const auto gc = label_counts(g);
  EXPECT_EQ(gc.size(), 3u);
  EXPECT_EQ(gc.at(1), c.at(1) + c.at(2));
  EXPECT_EQ(gc.at(300), c.at(3) + c.at(4));
}

// PAD=auto: a label map whose border holds one label needs no padding; a
// material cut by the border gets the border's majority label around it, and
// a box filled by materials a new outside label.
TEST(Labels, BorderPadding) {
  Volume v(VoxelType::u8, Dims{8, 8, 8});  // 512 voxels, 512 - 6^3 = 296 on the border
  EXPECT_EQ(border_label_counts(v).at(0), 296u);
  BorderPadding b;
  v.set(2, 2, 1, 7);  // an inner voxel: the border still holds only label 0
  b = border_padding(v);
  EXPECT_FALSE(b.pad);
  EXPECT_EQ(b.value, 0);
  EXPECT_EQ(b.border_labels, 1u);
  v.set(0, 2, 2, 5);  // a material touching the border at one voxel
  v.set(0, 3, 2, 5);
  b = border_padding(v);
  EXPECT_TRUE(b.pad);
  EXPECT_EQ(b.value, 0);  // 294 of 296 border voxels
  EXPECT_FALSE(b.new_label);
  EXPECT_EQ(border_label_counts(v).at(5), 2u);
  // Half the box is label 3, half label 4: no majority, a new label (largest + 1).
  Volume h(VoxelType::u8, Dims{8, 8, 8});
  for (std::size_t k = 0; k < 8; ++k)
    for (std::size_t j = 0; j < 8; ++j)
      for (std::size_t i = 0; i < 8; ++i) h.set(i, j, k, i < 4 ? 3 : 4);
  b = border_padding(h);
  EXPECT_TRUE(b.pad);
  EXPECT_TRUE(b.new_label);
  EXPECT_EQ(b.value, 5);
  EXPECT_EQ(b.border_labels, 2u);
  // A tiny volume (an axis below kTightenMinVoxels) is upsampled, not padded.
  Volume t(VoxelType::u8, Dims{2, 2, 2});
  t.set(1, 1, 1, 4);
  b = border_padding(t);
  EXPECT_FALSE(b.pad);
  EXPECT_EQ(b.border_labels, 2u);
}

TEST(Labels, RejectsNonIntegerData) {
  Volume v(VoxelType::f32, Dims{2, 2, 2});
  v.set(3, 0.5);
  EXPECT_THROW(require_labels(v, "x"), InputError);
  EXPECT_THROW(label_mask(v, {0}), InputError);
  Volume w(VoxelType::f32, Dims{2, 2, 2});
  w.set(3, 2.0);
  EXPECT_NO_THROW(require_labels(w, "x"));
}

TEST(Labels, TooManyDistinctValues) {
  Volume v(VoxelType::i32, Dims{100, 10, 1});
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i));
  EXPECT_THROW(label_counts(v, 100), InputError);
  EXPECT_EQ(label_counts(v).size(), 1000u);
}

TEST(Labels, DropSmallLabels) {
  // 10^3: label 1 for x < 5, label 2 beyond; a stray voxel of 7 inside 1 and
  // two voxels of 9 inside 2.
  Volume v(VoxelType::u8, Dims{10, 10, 10});
  for (std::size_t k = 0; k < 10; ++k)
    for (std::size_t j = 0; j < 10; ++j)
      for (std::size_t i = 0; i < 10; ++i) v.set(i, j, k, i < 5 ? 1 : 2);
  v.set(2, 2, 2, 7);
  v.set(7, 7, 7, 9);
  v.set(7, 7, 8, 9);
  std::vector<std::int64_t> dropped;
  const Volume w = drop_small_labels(v, 3, &dropped);
  EXPECT_EQ(dropped, (std::vector<std::int64_t>{7, 9}));
  EXPECT_EQ(w.type(), VoxelType::u8);
  const auto c = label_counts(w);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.at(1), 500u);
  EXPECT_EQ(c.at(2), 500u);
  EXPECT_EQ(w.get(2, 2, 2), 1.0);
  EXPECT_EQ(w.get(7, 7, 8), 2.0);
  // Nothing to drop: unchanged; everything too small: error.
  EXPECT_EQ(label_counts(drop_small_labels(w, 3)).size(), 2u);
  EXPECT_THROW(drop_small_labels(v, 100000), InputError);
}

}  // namespace
}  // namespace pm

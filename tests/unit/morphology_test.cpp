#include "pm/volume/morphology.h"

#include <gtest/gtest.h>

#include <cstdlib>

#include "pm/base/error.h"

namespace pm {
namespace {

std::size_t count_nonzero(const Volume& v) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < v.count(); ++i) n += v.get(i) != 0;
  return n;
}

Volume one_voxel(std::size_t n = 9) {
  Volume v(VoxelType::u8, Dims{n, n, n});
  v.set(n / 2, n / 2, n / 2, 1);
  return v;
}

/// uint8 box mask [lo, hi) on every axis.
Volume box(std::size_t n, std::size_t lo, std::size_t hi) {
  Volume v(VoxelType::u8, Dims{n, n, n});
  for (std::size_t k = lo; k < hi; ++k)
    for (std::size_t j = lo; j < hi; ++j)
      for (std::size_t i = lo; i < hi; ++i) v.set(i, j, k, 1);
  return v;
}

TEST(Morphology, SingleVoxelDilationGivesTheStencil) {
  const Volume v = one_voxel();
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::plus})), 7u);
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::ball})), 19u);
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::cube})), 27u);
  // The shapes, not only the counts: ball has no corners, plus no edges.
  const Volume b = dilate(v, {Stencil::ball}), p = dilate(v, {Stencil::plus});
  EXPECT_EQ(b.get(3, 3, 3), 0);
  EXPECT_EQ(b.get(3, 3, 4), 1);
  EXPECT_EQ(p.get(3, 3, 4), 0);
  EXPECT_EQ(p.get(3, 4, 4), 1);
  // Two iterations of plus: the L1 ball of radius 2 (1 + 6 + 18 = 25 voxels).
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::plus, 2})), 25u);
}

TEST(Morphology, CompositeStencilsOfTable21) {
  const Volume v = one_voxel(13);
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::f1})), 19u);  // f1 = ball
  // f2 = ball + cube: the 5^3 cube without its 8 corners (a corner needs a ball
  // offset with three non-zero components).
  EXPECT_EQ(count_nonzero(dilate(v, {Stencil::f2})), 125u - 8u);
  // f4 = p + b + c + p: 4 voxels along an axis; its parts move at most
  // 1 + 2 + 3 + 1 = 7 in L1, so (3,2,2) is in and (3,3,2) is not.
  const Volume f4 = dilate(v, {Stencil::f4});
  EXPECT_EQ(f4.get(6 + 4, 6, 6), 1);
  EXPECT_EQ(f4.get(6 + 5, 6, 6), 0);
  EXPECT_EQ(f4.get(6 + 3, 6 - 2, 6 + 2), 1);
  EXPECT_EQ(f4.get(6 + 3, 6 + 3, 6 - 2), 0);
  EXPECT_EQ(f4.get(6 + 2, 6 + 2, 6 + 2), 1);
  EXPECT_EQ(stencil_parts(Stencil::f3), (std::vector<Stencil>{Stencil::ball, Stencil::plus, Stencil::cube}));
}

TEST(Morphology, ErosionUndoesDilationOfAVoxel) {
  const Volume v = one_voxel(11);
  for (Stencil s : {Stencil::plus, Stencil::ball, Stencil::cube, Stencil::f2, Stencil::f4}) {
    const Volume e = erode(dilate(v, {s}), {s});
    EXPECT_EQ(count_nonzero(e), 1u) << stencil_name(s);
    EXPECT_EQ(e.get(5, 5, 5), 1) << stencil_name(s);
  }
}

TEST(Morphology, OpeningRemovesASpikeAndKeepsTheBox) {
  Volume v = box(20, 5, 15);
  v.set(15, 10, 10, 1);  // one-voxel spike on the +x face
  v.set(16, 10, 10, 1);
  const Volume cube = opening(v, {Stencil::cube});
  EXPECT_EQ(count_nonzero(cube), 1000u);  // a box is open for the cube stencil
  EXPECT_EQ(cube.get(15, 10, 10), 0);
  EXPECT_EQ(cube.get(5, 5, 5), 1);
  // The ball cannot rebuild the 8 box corners (they need a diagonal offset).
  const Volume ball = opening(v, {Stencil::ball});
  EXPECT_EQ(count_nonzero(ball), 1000u - 8u);
  EXPECT_EQ(ball.get(5, 5, 5), 0);
  EXPECT_EQ(ball.get(6, 5, 5), 1);
}

TEST(Morphology, ClosingFillsAOneVoxelHoleAndDent) {
  Volume v = box(20, 5, 15);
  v.set(10, 10, 10, 0);  // interior hole
  v.set(14, 8, 8, 0);    // dent in the +x face
  const Volume c = closing(v, {Stencil::ball});
  EXPECT_EQ(count_nonzero(c), 1000u);
  EXPECT_EQ(c.get(10, 10, 10), 1);
  EXPECT_EQ(c.get(14, 8, 8), 1);
  EXPECT_EQ(c.get(15, 8, 8), 0);
}

TEST(Morphology, OutsideIsBackground) {
  // A full volume is eroded from its border; closing a mask that touches the
  // border keeps it (the dilation is not clipped before the erosion).
  Volume full(VoxelType::u8, Dims{6, 7, 8});
  for (std::size_t i = 0; i < full.count(); ++i) full.set(i, 1);
  EXPECT_EQ(count_nonzero(erode(full, {Stencil::plus})), 4u * 5u * 6u);
  const Volume half = box(8, 0, 4);
  const Volume c = closing(half, {Stencil::f2});
  EXPECT_EQ(count_nonzero(c), 64u);
  EXPECT_EQ(c.get(0, 0, 0), 1);
}

// Erosion and dilation by their definition: voxel (i,j,k) of the result is the
// and (erosion) or or (dilation) of the mask over the stencil's offsets, with
// everything outside the volume background.
Volume brute_force(const Volume& m, Stencil s, bool dilate_op) {
  const Dims& d = m.dims();
  Volume out(VoxelType::u8, d);
  auto in = [&](long i, long j, long k) {
    return i >= 0 && j >= 0 && k >= 0 && i < long(d.nx) && j < long(d.ny) && k < long(d.nz) &&
           m.get(std::size_t(i), std::size_t(j), std::size_t(k)) != 0;
  };
  for (long k = 0; k < long(d.nz); ++k)
    for (long j = 0; j < long(d.ny); ++j)
      for (long i = 0; i < long(d.nx); ++i) {
        bool acc = !dilate_op;
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              const int l1 = std::abs(di) + std::abs(dj) + std::abs(dk);
              if ((s == Stencil::plus && l1 > 1) || (s == Stencil::ball && l1 > 2)) continue;
              const bool v = in(i + di, j + dj, k + dk);
              acc = dilate_op ? (acc || v) : (acc && v);
            }
        out.set(std::size_t(i), std::size_t(j), std::size_t(k), acc ? 1 : 0);
      }
  return out;
}

TEST(Morphology, RowsOfManyWordsMatchTheDefinition) {
  // The passes pack 64 voxels to a word along x: rows of 1, 2 and 3 words
  // (63, 64, 65, 130 voxels plus the region's margin) on a random mask.
  // Erosions of a mask 95% inside and dilations of one 5% inside, so that
  // most voxels at a word's edge change or keep their value by a neighbour
  // across it.
  std::uint64_t state = 12345;
  auto inside = [&](unsigned percent) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return (state >> 33) % 100 < percent;
  };
  for (std::size_t nx : {std::size_t(63), std::size_t(64), std::size_t(65), std::size_t(130)})
    for (bool dil : {false, true}) {
      Volume m(VoxelType::u8, Dims{nx, 6, 5});
      for (std::size_t c = 0; c < m.count(); ++c) m.set(c, inside(dil ? 5 : 95) ? 1 : 0);
      for (Stencil s : {Stencil::plus, Stencil::ball, Stencil::cube}) {
        const Volume got = dil ? dilate(m, {s}) : erode(m, {s});
        const Volume want = brute_force(m, s, dil);
        std::size_t differ = 0;
        for (std::size_t c = 0; c < m.count(); ++c) differ += got.get(c) != want.get(c);
        EXPECT_EQ(differ, 0u) << "nx " << nx << " " << stencil_name(s) << (dil ? " dilate" : " erode");
      }
  }
}

TEST(Morphology, ParseSteps) {
  const auto s = parse_morph_steps("close:f4, open:f2:3,erode");
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].op, MorphOp::close);
  EXPECT_EQ(s[0].stencil, Stencil::f4);
  EXPECT_EQ(s[1].iterations, 3);
  EXPECT_EQ(s[2].stencil, Stencil::ball);
  EXPECT_THROW(parse_morph_steps("shut:ball"), UsageError);
  EXPECT_THROW(parse_morph_steps("open:disc"), UsageError);
  EXPECT_THROW(parse_morph_steps("open:ball:0"), UsageError);
  EXPECT_THROW(parse_morph_steps(" , "), UsageError);
  EXPECT_THROW(dilate(one_voxel(), {Stencil::ball, 0}), UsageError);
}

TEST(Morphology, LabelsRecombineByRule) {
  // Background 0, label 1 on x < 5, label 2 on x >= 5 (inside a margin of 0).
  Volume v(VoxelType::i16, Dims{12, 5, 5});
  for (std::size_t k = 1; k < 4; ++k)
    for (std::size_t j = 1; j < 4; ++j)
      for (std::size_t i = 1; i < 11; ++i) v.set(i, j, k, i < 5 ? 1 : 2);
  LabelMorphParams p;
  p.steps = {MorphStep{MorphOp::dilate, Stencil::plus, 1}};
  const LabelMorphResult r = morph_labels(v, p);
  EXPECT_EQ(r.labels.type(), VoxelType::i16);
  // Both labels claim the interface voxels: each keeps its own label.
  EXPECT_EQ(r.labels.get(4, 2, 2), 1);
  EXPECT_EQ(r.labels.get(5, 2, 2), 2);
  // Background voxels claimed by both (above the interface) go to the smallest.
  EXPECT_EQ(r.labels.get(4, 0, 2), 1);
  EXPECT_EQ(r.labels.get(5, 0, 2), 2);
  EXPECT_EQ(r.labels.get(0, 2, 2), 1);
  EXPECT_EQ(r.labels.get(11, 2, 2), 2);
  EXPECT_EQ(r.labels.get(0, 0, 2), 0);  // edge-diagonal: not reached by plus
  EXPECT_EQ(r.empty, 0u);
  EXPECT_EQ(r.counts_before.at(1), 36u);
  EXPECT_EQ(r.counts_after.at(1) + r.counts_after.at(2) + r.counts_after.at(0), v.count());

  // With a background column x = 5 between them, both claim it: the smallest wins.
  for (std::size_t k = 1; k < 4; ++k)
    for (std::size_t j = 1; j < 4; ++j) v.set(5, j, k, 0);
  const LabelMorphResult g = morph_labels(v, p);
  EXPECT_EQ(g.labels.get(5, 2, 2), 1);
  EXPECT_EQ(g.labels.get(4, 2, 2), 1);
  EXPECT_EQ(g.labels.get(6, 2, 2), 2);
}

TEST(Morphology, LabelsOpeningLeavesEmptyVoxelsForVoting) {
  // Label 1 box with a spike into label 2's box; all of it surrounded by 0.
  Volume v(VoxelType::u8, Dims{24, 12, 12});
  for (std::size_t k = 1; k < 11; ++k)
    for (std::size_t j = 1; j < 11; ++j)
      for (std::size_t i = 1; i < 23; ++i) v.set(i, j, k, i < 11 ? 1 : 2);
  v.set(11, 5, 5, 1);  // spike of label 1 inside label 2
  LabelMorphParams p;
  p.steps = {MorphStep{MorphOp::open, Stencil::cube, 1}};
  LabelMorphResult r = morph_labels(v, p);
  // The spike voxel is no longer label 1, and label 2 never had it: empty -> fill 0.
  EXPECT_EQ(r.empty, 1u);
  EXPECT_EQ(r.labels.get(11, 5, 5), 0);
  p.vote = true;
  r = morph_labels(v, p);
  EXPECT_EQ(r.labels.get(11, 5, 5), 2);  // neighbours: 1, 2 x5
  EXPECT_EQ(r.vote_rounds, 1u);
  // Processing 0 as a material: the background is a 1-voxel shell along the
  // volume border (outside counts as background, i.e. in no mask), so opening
  // removes all of it; a material is never erased, so the shell keeps its input
  // voxels (a warning's worth: listed in `kept`) and only the spike is voted.
  p.labels = {0, 1, 2};
  r = morph_labels(v, p);
  EXPECT_EQ(r.labels.get(11, 5, 5), 2);
  const std::size_t shell = 24u * 12u * 12u - 22u * 10u * 10u;
  EXPECT_EQ(r.counts_after.at(0), shell);
  EXPECT_EQ(r.empty, 1u);
  ASSERT_EQ(r.kept.size(), 1u);
  EXPECT_EQ(r.kept[0].label, 0);
  EXPECT_EQ(r.kept[0].stage, "morphology");
  EXPECT_EQ(r.kept[0].voxels, shell);
  // all_labels: every label present, 0 included, as the explicit list.
  LabelMorphParams all = p;
  all.labels.clear();
  all.all_labels = true;
  const LabelMorphResult a = morph_labels(v, all);
  EXPECT_EQ(a.counts_after, r.counts_after);
  for (std::size_t c = 0; c < v.count(); ++c) ASSERT_EQ(a.labels.get(c), r.labels.get(c)) << c;
  p.labels = {7};
  EXPECT_THROW(morph_labels(v, p), InputError);
}

TEST(Morphology, PerLabelSequences) {
  // Label 1 with a hole, label 2 with a hole: close only label 2.
  Volume v(VoxelType::u8, Dims{20, 10, 10});
  for (std::size_t k = 1; k < 9; ++k)
    for (std::size_t j = 1; j < 9; ++j)
      for (std::size_t i = 1; i < 19; ++i) v.set(i, j, k, i < 10 ? 1 : 2);
  v.set(5, 5, 5, 0);
  v.set(14, 5, 5, 0);
  LabelMorphParams p;
  p.per_label[2] = {MorphStep{MorphOp::close, Stencil::ball, 1}};
  const LabelMorphResult r = morph_labels(v, p);
  EXPECT_EQ(r.labels.get(5, 5, 5), 0);
  EXPECT_EQ(r.labels.get(14, 5, 5), 2);
}

TEST(Morphology, VotingFillsEveryEmptyVoxelTiesToSmallest) {
  Volume line(VoxelType::u8, Dims{3, 1, 1});
  line.set(0, 7);
  line.set(2, 3);
  VoteResult r = vote_fill(line, 0);
  EXPECT_EQ(r.labels.get(1), 3);  // tie 3 vs 7 -> 3
  EXPECT_EQ(r.filled, 1u);

  // An empty slab x = 3..8 between labels 4 (x < 3) and 9 (x >= 9) fills from
  // both sides, one layer per round: x=3 and 8, then 4 and 7, then 5 and 6.
  Volume v(VoxelType::i32, Dims{12, 4, 3});
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t j = 0; j < 4; ++j)
      for (std::size_t i = 0; i < 12; ++i) v.set(i, j, k, i < 3 ? 4 : (i >= 9 ? 9 : -1));
  r = vote_fill(v, -1);
  EXPECT_EQ(r.filled, 6u * 12u);
  EXPECT_EQ(r.rounds, 3u);
  for (std::size_t i = 0; i < v.count(); ++i) ASSERT_NE(r.labels.get(i), -1);
  EXPECT_EQ(r.labels.get(5, 1, 1), 4);
  EXPECT_EQ(r.labels.get(6, 1, 1), 9);
  // Odd gap: x = 3..7 empty between 4 and 9 at x = 8: the middle x = 5 is a tie -> 4.
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t j = 0; j < 4; ++j) v.set(8, j, k, 9);
  r = vote_fill(v, -1);
  EXPECT_EQ(r.labels.get(5, 2, 1), 4);
  EXPECT_EQ(r.labels.get(6, 2, 1), 9);

  Volume all_empty(VoxelType::u8, Dims{2, 2, 2});
  EXPECT_THROW(vote_fill(all_empty, 0), InputError);
}

TEST(Morphology, SmallComponentsRemovedAndRefilled) {
  // A 6^3 box (216 voxels) with a one-voxel cavity at its centre, a 2-voxel
  // speck and a one-voxel speck outside it, and a diagonal (edge-touching)
  // voxel that is its own 6-connected component.
  Volume v = box(16, 2, 8);
  v.set(5, 5, 5, 0);
  v.set(12, 12, 12, 1);
  v.set(13, 12, 12, 1);
  v.set(12, 3, 3, 1);
  v.set(8, 8, 7, 1);  // touches the box's edge voxel (7,7,7) only diagonally: own component
  LabelMorphParams p;
  p.min_component = 3;
  LabelMorphResult r = morph_labels(v, p);
  EXPECT_EQ(r.components_removed, 4u);          // cavity, 2-voxel speck, 1-voxel speck, diagonal voxel
  EXPECT_EQ(r.component_voxels_removed, 5u);    // 1 + 2 + 1 + 1
  EXPECT_EQ(r.labels.get(5, 5, 5), 1);          // cavity filled from its 6 inside neighbours
  EXPECT_EQ(r.labels.get(12, 12, 12), 0);
  EXPECT_EQ(r.labels.get(13, 12, 12), 0);
  EXPECT_EQ(r.labels.get(12, 3, 3), 0);
  EXPECT_EQ(r.labels.get(8, 8, 7), 0);
  EXPECT_EQ(count_nonzero(r.labels), 216u);     // exactly the full box
  EXPECT_EQ(r.empty, 5u);                       // the removed voxels, all refilled by voting
  // A threshold of 2 keeps the 2-voxel speck.
  p.min_component = 2;
  r = morph_labels(v, p);
  EXPECT_EQ(r.components_removed, 3u);
  EXPECT_EQ(r.labels.get(12, 12, 12), 1);
  EXPECT_EQ(count_nonzero(r.labels), 218u);
}

TEST(Morphology, DownsampleMajorityAndMean) {
  Geometry g = Geometry::with_spacing(1, 2, 3, Vec3(10, 20, 30));
  Volume v(VoxelType::u16, Dims{4, 4, 5}, g);
  // Block (0,0,0): 5 voxels of 3, 3 of 1. Block (1,0,0): 4 of 6 and 4 of 5 -> tie -> 5.
  for (std::size_t k = 0; k < 2; ++k)
    for (std::size_t j = 0; j < 2; ++j)
      for (std::size_t i = 0; i < 2; ++i) {
        v.set(i, j, k, (i + j + k) < 2 || (i == 1 && j == 1 && k == 0) ? 3 : 1);
        v.set(i + 2, j, k, k == 0 ? 6 : 5);
      }
  const Volume d = downsample(v, 2, DownsampleMode::majority);
  EXPECT_EQ(d.dims(), (Dims{2, 2, 3}));  // ceil(5/2) = 3
  EXPECT_EQ(d.get(0, 0, 0), 3);
  EXPECT_EQ(d.get(1, 0, 0), 5);
  EXPECT_EQ(d.type(), VoxelType::u16);
  EXPECT_DOUBLE_EQ(d.geometry().spacing(1), 4.0);
  EXPECT_DOUBLE_EQ(d.geometry().origin.x, 10.5);
  EXPECT_DOUBLE_EQ(d.geometry().origin.z, 31.5);

  Volume grey(VoxelType::f32, Dims{4, 2, 2});
  for (std::size_t i = 0; i < grey.count(); ++i) grey.set(i, double(i));
  const Volume m = downsample(grey, 2, DownsampleMode::mean);
  // Block 0: voxels 0,1,4,5,8,9,12,13 -> mean 6.5.
  EXPECT_FLOAT_EQ(float(m.get(0)), 6.5f);
  EXPECT_FLOAT_EQ(float(m.get(1)), 8.5f);
  EXPECT_THROW(downsample(grey, 0, DownsampleMode::mean), UsageError);

  // Through morph_labels: downsample and vote.
  LabelMorphParams p;
  p.downsample = 2;
  const LabelMorphResult r = morph_labels(v, p);
  EXPECT_EQ(r.labels.get(0, 0, 0), 3);
  EXPECT_EQ(r.labels.dims(), (Dims{2, 2, 3}));
}

TEST(Morphology, NeverErasesAMaterial) {
  // 2x2x2, five labels: 0 on four voxels, 1..4 one voxel each. Closing then opening
  // with the ball erases every one of them; each keeps its input voxels instead.
  Volume v(VoxelType::u8, Dims{2, 2, 2});
  for (std::size_t i = 0; i < 4; ++i) v.set(4 + i, std::uint8_t(1 + i));
  LabelMorphParams p;
  p.steps = parse_morph_steps("close:ball,open:ball");
  p.labels = {0, 1, 2, 3, 4};
  p.vote = true;
  LabelMorphResult r = morph_labels(v, p);
  ASSERT_EQ(r.kept.size(), 5u);
  for (std::size_t i = 0; i < v.count(); ++i) EXPECT_EQ(r.labels.get(i), v.get(i)) << "voxel " << i;
  EXPECT_EQ(r.kept[0].voxels, 4u);
  EXPECT_EQ(r.kept[4].label, 4);
  EXPECT_EQ(r.kept[4].voxels, 1u);
  EXPECT_TRUE(r.lost.empty());

  // Downsampling 2x to one voxel cannot keep five labels: the majority 0 stays,
  // the four others are reported lost (not silently gone).
  p.downsample = 2;
  r = morph_labels(v, p);
  EXPECT_EQ(r.labels.count(), 1u);
  EXPECT_EQ(r.labels.get(0), 0);
  EXPECT_EQ(r.lost, (std::vector<std::int64_t>{1, 2, 3, 4}));

  // A one-voxel material in a 4^3 background: downsampling by 2 would outvote it; it
  // takes its own block instead.
  Volume speck(VoxelType::u8, Dims{4, 4, 4});
  speck.set(3, 2, 1, 7);
  LabelMorphParams d;
  d.downsample = 2;
  r = morph_labels(speck, d);
  EXPECT_EQ(r.labels.get(1, 1, 0), 7);
  EXPECT_EQ(r.counts_after.at(7), 1u);
  ASSERT_EQ(r.kept.size(), 1u);
  EXPECT_EQ(r.kept[0].stage, "downsample");

  // Every component of label 2 below --min-component: its largest stays.
  Volume comps = box(10, 1, 7);
  comps.set(8, 8, 8, 2);
  comps.set(8, 8, 7, 2);
  comps.set(8, 1, 1, 2);
  LabelMorphParams c;
  c.min_component = 5;
  r = morph_labels(comps, c);
  EXPECT_EQ(r.labels.get(8, 8, 8), 2);
  EXPECT_EQ(r.labels.get(8, 8, 7), 2);
  EXPECT_NE(r.labels.get(8, 1, 1), 2);
  EXPECT_EQ(r.components_removed, 1u);
  ASSERT_EQ(r.kept.size(), 1u);
  EXPECT_EQ(r.kept[0].label, 2);
  EXPECT_EQ(r.kept[0].stage, "min_component");
  EXPECT_EQ(r.kept[0].voxels, 2u);
}

}  // namespace
}  // namespace pm

#pragma once
// Binary morphology on masks and label maps (SPEC §2, dissertation §2.5.1 and
// §6.6.1): erosion, dilation, opening and closing with the three isotropic
// 3x3x3 stencils and the composite stencils of Table 2.1; per-material
// processing of label maps, recombination, downsampling and voting fill.
//
// Everything here works in voxels (stencils, iterations, factors); world
// geometry only changes through downsample(). Voxels outside the volume count
// as background (not in any mask), so the domain behaves as if padded with
// background forever: a dilation is never clipped before a later erosion
// (closing stays a superset of its input), and a mask touching the border is
// eroded from the border.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

enum class MorphOp { erode, dilate, open, close };

/// Stencils. The three basic ones are 3x3x3: plus = centre + 6 face
/// neighbours (7 voxels), ball = cube minus its 8 corners (19 voxels),
/// cube = all 27 voxels. f1..f4 are Table 2.1's round composite stencils for
/// feature sizes 1..4: f1 = b, f2 = b+c, f3 = (b+p)+c, f4 = (p+b)+c+p, where
/// + is dilation of stencils; a composite is applied as successive passes of
/// its parts.
enum class Stencil { plus, ball, cube, f1, f2, f3, f4 };

/// "erode" "dilate" "open" "close". \throw UsageError listing the choices.
MorphOp parse_morph_op(const std::string& name);
const char* morph_op_name(MorphOp op);
/// "plus" "ball" "cube" "f1".."f4". \throw UsageError listing the choices.
Stencil parse_stencil(const std::string& name);
const char* stencil_name(Stencil s);
/// The basic stencils (plus/ball/cube) a stencil is applied as, in order.
std::vector<Stencil> stencil_parts(Stencil s);

/// One step of an operation sequence: `op` with `stencil`, `iterations`
/// times. For open/close the iterations are nested: open with N iterations
/// erodes N times, then dilates N times (opening by the N-fold stencil).
struct MorphStep {
  MorphOp op = MorphOp::open;
  Stencil stencil = Stencil::ball;
  int iterations = 1;  ///< >= 1
};

/// Parse a sequence "close:f4,open:f2" or "erode:plus:3" (op:stencil[:iterations],
/// comma-separated, applied left to right; the stencil defaults to ball).
/// \throw UsageError naming the bad item and the expected form.
std::vector<MorphStep> parse_morph_steps(const std::string& spec);

struct MorphParams {
  Stencil stencil = Stencil::ball;
  int iterations = 1;  ///< >= 1
};

/// Binary morphology of a mask (voxels != 0 are inside). Result: uint8 0/1
/// with the input's dims and geometry.
/// \throw UsageError when iterations < 1.
Volume morph_mask(const Volume& mask, const std::vector<MorphStep>& steps);
Volume erode(const Volume& mask, const MorphParams& p = {});
Volume dilate(const Volume& mask, const MorphParams& p = {});
/// Opening (erode then dilate): removes features thinner than the stencil.
/// (Named `opening`/`closing` so that they do not hide POSIX open/close.)
Volume opening(const Volume& mask, const MorphParams& p = {});
/// Closing (dilate then erode): fills gaps and holes narrower than the stencil.
Volume closing(const Volume& mask, const MorphParams& p = {});

/// Per-material processing of a label map (§6.6.1), in this order:
///  1. Every processed label's mask goes through its step sequence separately.
///  2. Recombination, per voxel with original label o, C = the processed
///     labels whose result contains it: o if o is in C; else the smallest
///     label in C; else o if o is not processed (a passive label, typically the
///     background 0, keeps what no processed label claims); else the voxel is
///     empty (it was eroded out of its material and nobody claimed it).
///  3. Downsampling by `downsample` (see downsample()): the majority label of
///     each block, ignoring empty voxels; ties go to the smallest label; a
///     block of only empty voxels stays empty.
///  4. With `vote`: voting fill (see vote_fill()) of the empty voxels, where
///     every label votes, processed or passive. Without it empty voxels get
///     `fill`.
/// A background label 0 is an ordinary label: passive unless listed in
/// `labels` (then it is opened/closed like any material, e.g. Table 6.1's
/// air) and a voter either way.
/// No stage erases a material (a label present in the input) silently: when
/// the morphology would leave a processed label no voxel, its input voxels are
/// given back to it (a passive label that processed labels' dilations cover
/// is not kept: that was asked for); when downsampling would, the output voxel whose block holds most of it
/// (and whose own label keeps other voxels) takes it; when min_component would
/// remove every component of a label, its largest component stays. Each case is
/// listed in LabelMorphResult::kept (the caller warns); a label that cannot be
/// kept (a downsampled grid with fewer voxels than labels) is listed in `lost`.
struct LabelMorphParams {
  std::vector<MorphStep> steps;  ///< applied to every processed label
  /// Sequences for particular labels: override `steps` for them, and make
  /// them processed labels even when `labels` does not list them.
  std::map<std::int64_t, std::vector<MorphStep>> per_label;
  /// Processed labels; empty = every non-zero label present. Labels listed
  /// but absent are an error.
  std::vector<std::int64_t> labels;
  bool all_labels = false;  ///< process every label present, 0 included (overrides `labels`)
  int downsample = 1;     ///< integer factor >= 1 (voxels per output voxel per axis)
  bool vote = false;      ///< fill empty voxels by voting
  std::int64_t fill = 0;  ///< value of empty voxels when vote is false
  /// After morphology and downsampling: remove every 6-connected component
  /// of a label (background included) with fewer voxels than this and fill
  /// it by voting (implies vote). 0 or 1 = keep all.
  std::size_t min_component = 0;
};

/// A material that a stage of morph_labels would have erased and kept instead.
struct KeptLabel {
  std::int64_t label = 0;
  std::string stage;       ///< "morphology", "downsample" or "min_component"
  std::size_t voxels = 0;  ///< voxels it kept (at that stage's resolution)
};

struct LabelMorphResult {
  Volume labels;  ///< input voxel type; downsampled dims and geometry
  std::vector<KeptLabel> kept;      ///< materials kept against the stage (see morph_labels)
  std::vector<std::int64_t> lost;   ///< materials that could not be kept (downsampled grid too small)
  std::map<std::int64_t, std::size_t> counts_before, counts_after;
  std::size_t empty = 0;        ///< empty voxels after step 3
  std::size_t vote_rounds = 0;  ///< voting rounds run (0 without vote)
  std::size_t components_removed = 0;        ///< components below min_component
  std::size_t component_voxels_removed = 0;  ///< their voxels (refilled by voting)
};

/// \throw InputError for non-integer voxel values, absent labels, more than
/// 65535 distinct labels, or when voting has nothing to vote from (every
/// voxel empty). \throw UsageError for downsample < 1 or iterations < 1.
LabelMorphResult morph_labels(const Volume& labels, const LabelMorphParams& p);

struct VoteResult {
  Volume labels;
  std::size_t filled = 0;  ///< voxels that were empty
  std::size_t rounds = 0;
};

/// Voting fill (§6.6.1): every voxel whose value is `empty` takes the most
/// common label among its (up to 6) non-empty face neighbours; ties go to the
/// smallest label; voxels with no non-empty neighbour wait. Rounds are
/// simultaneous (each round reads the previous one, so the result does not
/// depend on traversal order) and repeat until no voxel is empty.
/// \throw InputError when the volume is empty everywhere or not a label map.
VoteResult vote_fill(const Volume& labels, std::int64_t empty = 0);

enum class DownsampleMode {
  majority,  ///< label maps: most common value of the block, ties -> smallest
  mean,      ///< grey values: block mean, rounded to the voxel type
};

/// Downsample by an integer factor k >= 1 (voxels). Output dims are
/// ceil(n / k); a last, partial block uses only the voxels inside the volume.
/// Geometry: each direction column (spacing) times k, origin moved to the
/// centre of the first block, origin + D * ((k-1)/2, (k-1)/2, (k-1)/2).
/// \throw UsageError for k < 1; InputError for majority on non-labels.
Volume downsample(const Volume& v, int k, DownsampleMode mode);

}  // namespace pm

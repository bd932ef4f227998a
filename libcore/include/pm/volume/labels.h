#pragma once
// Everyday label-map chores: masks of chosen labels, relabelling (merging),
// and label statistics.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

/// One merge rule: every label in `from` becomes `to`.
struct MergeRule {
  std::vector<std::int64_t> from;
  std::int64_t to = 0;
};

/// Parse "1,2:1 3,4:2" (space- or semicolon-separated rules "a,b,...:target").
/// \throw UsageError naming the bad rule and the expected form.
std::vector<MergeRule> parse_merge_spec(const std::string& spec);
/// Parse "2,41" or "2-5,7". \throw UsageError.
std::vector<std::int64_t> parse_label_list(const std::string& spec);

/// \throw InputError if any voxel is not an integer value (float volumes with
/// integral values are accepted). `what` names the input in the message.
void require_labels(const Volume& v, const std::string& what);

/// uint8 mask: 1 where the voxel's label is in `labels`, 0 elsewhere.
/// \throw InputError when none of the labels occurs (lists the labels present).
Volume label_mask(const Volume& labels, const std::vector<std::int64_t>& which, const std::string& what = "labels");

/// Relabel by rules; labels not named keep their value. Output keeps the
/// input voxel type unless a target does not fit it (then int32).
Volume merge_labels(const Volume& labels, const std::vector<MergeRule>& rules);

/// Drop labels with fewer than `min_voxels` voxels (stray labels): each of
/// their voxels takes the most common kept label among its face neighbours,
/// growing inward from the kept regions (ties: the smallest label). Labels
/// dropped are appended to `dropped` when given. The voxel type is kept.
/// \throw InputError for non-integer values or when no label has min_voxels voxels.
Volume drop_small_labels(const Volume& labels, std::size_t min_voxels, std::vector<std::int64_t>* dropped = nullptr);

/// Voxel count per label value. \throw InputError for more than `max_labels`
/// distinct values (a grey-level volume, not a label map).
std::map<std::int64_t, std::size_t> label_counts(const Volume& labels, std::size_t max_labels = 65536);

/// Voxel count per label on the volume's six border faces (each border voxel
/// once). \throw InputError as label_counts.
std::map<std::int64_t, std::size_t> border_label_counts(const Volume& labels);

/// Padding of a label map whose materials reach the volume border (the
/// materials pipeline's `PAD=auto`): none when one label fills the whole
/// border (it is the outside material, e.g. the background of a cropped
/// scan) and on tiny volumes (an axis below kTightenMinVoxels: tighten
/// upsamples them, and their hull is their box); else `pad` = true and `value` = the label holding more than half of
/// the border voxels (the background of a scan cut through the body: only the
/// cut materials get new faces), or one more than the largest label (a new
/// outside material, for maps whose materials fill their box).
struct BorderPadding {
  bool pad = false;
  std::int64_t value = 0;
  bool new_label = false;  ///< value is a new label (one more than the largest)
  std::size_t border_labels = 0;  ///< distinct labels on the border
};
BorderPadding border_padding(const Volume& labels);
/// The value of padding voxels from `--pad-value` / PAD_VALUE: "auto" (the
/// border_padding value), "new" (one more than the largest label) or a finite
/// number. \throw UsageError for anything else; InputError (naming `what`) when
/// "auto" or "new" meets a volume that is not a label map.
double pad_value_of(const Volume& labels, const std::string& spec, const std::string& what);

/// Voxels of padding `--pad auto` adds when the border needs it.
constexpr std::size_t kAutoPadVoxels = 3;

}  // namespace pm

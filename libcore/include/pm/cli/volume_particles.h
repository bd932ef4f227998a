#pragma once
// The volume-packing run of the `particles` tool (`--volume`, SPEC §7,
// issue #19): free particles inside one region (F < iso of -i/--implicit) or
// inside every material of a set (--materials), repelled by the fixed
// vertices of the final surface or interface mesh (--fixed). Writes the free
// particles (world units) with their `spacing` and material `label`.
#include <string>

#include "pm/cli/material_options.h"
#include "pm/field/field.h"
#include "pm/io/frame.h"
#include "pm/sample/volume_packing.h"

namespace pm {

struct VolumeRun {
  const ScalarField* field = nullptr;  ///< one region (the `inside` side of iso), or null with materials
  double iso = 0;
  /// One region: which side is the material, "below" (F < iso, distance
  /// fields), "above" (masks, CT) or "auto" (pm::material_below_iso).
  std::string inside = "auto";
  const MaterialOptions* materials = nullptr;  ///< several materials, or null
  std::string outside = "auto";        ///< materials: the label not packed (auto: pm::auto_outside_label)
  std::string fixed;                   ///< surface / interface mesh whose vertices are fixed
  std::string sizing;                  ///< sizing volume, or "" for the constant params.spacing
  VolumePackParams params;
  std::string output;
  WorldFrame frame = WorldFrame::lps;
};

/// \throw UsageError for a missing --fixed, both or neither of a field and
/// materials, --outside not an integer; InputError for bad files (named).
void run_volume(VolumeRun run);

}  // namespace pm

#pragma once
// The anatomical frame a mesh or point file is written in. libcore's world
// frame is LPS (x to the patient's left, y to posterior, z to superior), as in
// ITK, DICOM, MetaImage and 3D Slicer's files. RAS (NIfTI, FreeSurfer, older
// Slicer models) negates x and y.
#include <string>

#include "pm/base/mesh.h"

namespace pm {

enum class WorldFrame { lps, ras };

/// "LPS" or "RAS".
const char* frame_name(WorldFrame f);

/// "lps" / "ras" (any case) -> the frame.
/// \throw UsageError `--frame "xyz": unknown frame; expected lps or ras`.
WorldFrame parse_frame(const std::string& s, const std::string& option = "--frame");

/// Convert a mesh between LPS and RAS in place (negate x and y of vertices and
/// normals; the same map both ways). Winding is kept: the map is a rotation by
/// 180 degrees about z, so outward normals stay outward.
void convert_frame(Mesh& m, WorldFrame from, WorldFrame to);

/// Which frame a header comment states: "SPACE=RAS" / "frame RAS" -> ras,
/// "SPACE=LPS" / "frame LPS" -> lps; false when it states none.
bool frame_from_comment(const std::string& text, WorldFrame& f);

}  // namespace pm

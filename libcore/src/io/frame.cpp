#include "pm/io/frame.h"

#include <cctype>

#include "pm/base/error.h"

namespace pm {

const char* frame_name(WorldFrame f) { return f == WorldFrame::ras ? "RAS" : "LPS"; }

WorldFrame parse_frame(const std::string& s, const std::string& option) {
  std::string l;
  for (char c : s) l += char(std::tolower(static_cast<unsigned char>(c)));
  if (l == "lps") return WorldFrame::lps;
  if (l == "ras") return WorldFrame::ras;
  throw UsageError(option + " " + quote(s) + ": unknown frame; expected lps or ras");
}

void convert_frame(Mesh& m, WorldFrame from, WorldFrame to) {
  if (from == to) return;
  for (Vec3& v : m.vertices) v = Vec3(-v.x, -v.y, v.z);
  for (Vec3& n : m.normals) n = Vec3(-n.x, -n.y, n.z);
}

bool frame_from_comment(const std::string& text, WorldFrame& f) {
  for (const char* ras : {"SPACE=RAS", "frame RAS"})
    if (text.find(ras) != std::string::npos) {
      f = WorldFrame::ras;
      return true;
    }
  for (const char* lps : {"SPACE=LPS", "frame LPS"})
    if (text.find(lps) != std::string::npos) {
      f = WorldFrame::lps;
      return true;
    }
  return false;
}

}  // namespace pm

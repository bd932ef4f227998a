#include "pm/cli/frame_option.h"

#include <string>

#include "pm/base/error.h"

namespace pm {

CLI::Option* add_frame_option(CLI::App& app, WorldFrame& frame) {
  const auto valid = [](const std::string& s) -> std::string {
    try {
      parse_frame(s);
      return "";
    } catch (const UsageError&) {
      return quote(s) + ": unknown frame; expected lps or ras";
    }
  };
  return app
      .add_option("--frame")
      ->description(
                  "Anatomical frame of the written coordinates: lps (libcore's world frame, as ITK, DICOM and 3D "
                  "Slicer files; default) or ras (x and y negated, as NIfTI and FreeSurfer). Stated in the file "
                  "(PLY comment, VTK SPACE=, MEDIT/OBJ/Gmsh comment) so that Slicer places the mesh on its volume")
      ->type_name("lps|ras")
      ->check(CLI::Validator(valid, "lps|ras"))
      ->each([&frame](const std::string& s) { frame = parse_frame(s); })
      ->default_str("lps");
}

}  // namespace pm

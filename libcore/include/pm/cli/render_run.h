#pragma once
// The `render` run: a point set, surface, polygon or tetrahedral mesh to a
// PNG (pm/render/render.h, pm/render/tet_render.h), parameters into pm::stats().
#include <CLI/CLI.hpp>
#include <string>

#include "pm/render/render.h"

namespace pm {

struct RenderRun {
  std::string input, output;
  std::string size = "800x800";  ///< WxH, pixels
  RenderParams params;
};

void add_render_options(CLI::App& app, RenderRun& r);
/// \throw UsageError for a bad --size or output, InputError for bad input.
void run_render(RenderRun& r);

}  // namespace pm

#pragma once
// --frame lps|ras, for every tool that writes meshes or point sets.
#include <CLI/CLI.hpp>

#include "pm/io/frame.h"

namespace pm {

/// Adds `--frame lps|ras` (any case; default lps) to `app`; another value is
/// a usage error (exit 2) at parse time.
CLI::Option* add_frame_option(CLI::App& app, WorldFrame& frame);

}  // namespace pm

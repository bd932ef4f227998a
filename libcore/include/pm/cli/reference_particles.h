#pragma once
// The Chapter 4 runs of the `particles` tool: particles in the reference
// spaces of a Nektar++ field (`-i mesh.xml --field f.fld:VARIABLE`) or of a
// built-in scenario (`--scenario teardrop|hex8`), written as a
// double-precision PLY (element, xi1..3, residual, energy, spacing) with
// their statistics in pm::stats().
#include <string>

#include "pm/io/frame.h"
#include "pm/sample/particles.h"

namespace pm {

/// `field_arg` is FILE.fld:VARIABLE. \throw UsageError for a malformed
/// --field, another --frame than lps or a non-.ply output; InputError for bad
/// files or a variable the field lacks.
void run_hp(const std::string& mesh_path, const std::string& field_arg, const ParticleParams& p,
            const std::string& output, WorldFrame frame);

/// `name` is teardrop (F* = |u - c|^2 on B-spline-mapped elements, default
/// iso 0.16) or hex8 (u = x^8 + y^8 + z^8 in [-1,1]^3, default iso 0.5).
void run_scenario(const std::string& name, ParticleParams p, bool iso_given, const std::string& output);

}  // namespace pm

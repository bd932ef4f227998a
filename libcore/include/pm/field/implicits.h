#pragma once
// Analytic implicit surfaces with exact gradients and Hessians, all with F < 0
// inside. Parsed from specs such as "sphere", "sphere:r=2", "torus:R=1,r=0.4",
// "tangle", "box:a=1,b=1,c=1,r=0.2", "twospheres:r=1,d=1.2".
#include <memory>
#include <string>

#include "pm/field/field.h"

namespace pm {

/// Build a field from a spec string. \throw UsageError for an unknown name,
/// an unknown or non-positive parameter, with the list of valid ones.
std::unique_ptr<ScalarField> make_implicit(const std::string& spec);

/// Names and parameters, for --help.
std::string implicit_help();

}  // namespace pm

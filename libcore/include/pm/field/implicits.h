#pragma once
// Analytic implicit surfaces with exact gradients and Hessians, all with F < 0
// inside. Parsed from specs such as "sphere", "sphere:r=2", "torus:R=1,r=0.4",
// "tangle", "box:a=1,b=1,c=1,r=0.2", "twospheres:r=1,d=1.2".
//
//   sphere[:r,cx,cy,cz]  F = |x - c| - r (signed distance)
//   torus[:R,r]          F = sqrt((sqrt(x²+y²) - R)² + z²) - r, around the z
//                        axis, requires r < R (signed distance)
//   tangle[:s]           F = Σ (x_i/s)⁴ - 5 (x_i/s)² + 11.8 (not a distance)
//   box[:a,b,c,r]        box with half-extents a,b,c, edges and corners rounded
//                        by r <= min(a,b,c), centred at 0 (signed distance)
//   twospheres[:r,d]     min of the distances to spheres of radius r at
//                        (±d/2,0,0): a sharp crease where they meet (exact
//                        distance outside, a bound inside)
// Where the gradient is undefined (sphere centre, torus core circle, box
// medial planes, the twospheres crease) a one-sided value is returned, and 0
// at isolated points. domain() is the bounding box of the surface plus 10% of
// its largest half-extent; resolution() is the smallest radius of curvature
// (or feature scale s) / 50.
#include <memory>
#include <string>

#include "pm/field/field.h"

namespace pm {

/// Build a field from a spec string "name[:key=value,...]". \throw UsageError
/// for an unknown name, an unknown, repeated, non-numeric or non-positive
/// parameter (centres may be any number), r >= R for the torus or
/// r > min(a,b,c) for the box, with the list of valid names or parameters.
std::unique_ptr<ScalarField> make_implicit(const std::string& spec);

/// One line for --help: each name with its parameters, their defaults and a
/// few words ("sphere[:r=1,cx=0,cy=0,cz=0] sphere of radius r ...; torus...").
std::string implicit_help();

}  // namespace pm

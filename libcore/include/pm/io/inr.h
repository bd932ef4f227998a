#pragma once
// INRimage (.inr, .inr.gz): 256-byte-multiple text header + raw voxels.
//
// Header "#INRIMAGE-4#{" ... "##}" with XDIM YDIM ZDIM, VDIM (must be 1),
// TYPE (unsigned fixed, signed fixed: 8/16/32/64 bits; float: 32/64 bits),
// PIXSIZE, CPU (decm, alpha, pc: little endian; sun, sgi, mips: big endian;
// absent: little), VX VY VZ (spacing, default 1), TX TY TZ (origin, default 0).
// SCALE is ignored. .inr.gz is read and written through zlib. INRimage has
// no world frame: coordinates are taken as LPS (libcore's frame).
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (bad header, truncated data).
Volume read_inr(const std::string& path);
/// INRimage holds only positive per-axis spacings and an origin: an axis
/// with a negative step (e.g. x and y of a RAS NIfTI in LPS) is written
/// reversed, with the origin at its other end, so every voxel keeps its
/// world position. \throw InputError when the directions are oblique; IoError.
void write_inr(const Volume& v, const std::string& path);
}  // namespace pm

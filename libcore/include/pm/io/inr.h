#pragma once
// INRimage (.inr, .inr.gz): 256-byte-multiple text header + raw voxels.
#include <string>

#include "pm/base/volume.h"

namespace pm {
Volume read_inr(const std::string& path);
void write_inr(const Volume& v, const std::string& path);
}  // namespace pm

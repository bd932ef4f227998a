#pragma once
// MetaImage (.mha single file, .mhd + .raw/.zraw).
#include <string>

#include "pm/base/volume.h"

namespace pm {
Volume read_metaimage(const std::string& path);
void write_metaimage(const Volume& v, const std::string& path, bool compress = true);
}  // namespace pm

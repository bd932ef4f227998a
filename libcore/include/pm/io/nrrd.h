#pragma once
// NRRD (.nrrd attached, .nhdr detached; raw or gzip) through Teem.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError, InputError (see read_volume).
Volume read_nrrd(const std::string& path);
/// Writes `path` directly (callers use write_volume for atomicity). For .nhdr
/// the data file is written beside it.
void write_nrrd(const Volume& v, const std::string& path, bool gzip = true);
}  // namespace pm

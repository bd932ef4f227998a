#include "pm/base/error.h"

namespace pm {
std::string quote(const std::string& s) { return "\"" + s + "\""; }
}  // namespace pm

#include "pm/base/error.h"

#include <cstdio>

namespace pm {
std::string quote(const std::string& s) { return "\"" + s + "\""; }

std::string format_number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}
}  // namespace pm

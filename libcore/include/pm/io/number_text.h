#pragma once
// Numbers as text in the ASCII writers: enough significant digits that the
// text reads back to the same value (17 for a double, 9 for a float).
#include <cstdio>
#include <string>

namespace pm {

constexpr int kDoubleDigits = 17;
constexpr int kFloatDigits = 9;

/// Appends v with `digits` significant digits (%.*g).
inline void append_number(std::string& out, double v, int digits = kDoubleDigits) {
  char b[40];
  const int n = std::snprintf(b, sizeof b, "%.*g", digits, v);
  out.append(b, std::size_t(n));
}

/// v with `digits` significant digits (%.*g).
inline std::string number_text(double v, int digits = kDoubleDigits) {
  std::string s;
  append_number(s, v, digits);
  return s;
}

}  // namespace pm

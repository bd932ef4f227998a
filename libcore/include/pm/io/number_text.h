#pragma once
// Numbers as text in the ASCII writers: enough significant digits that the
// text reads back to the same value (17 for a double, 9 for a float).
#include <charconv>
#include <string>

namespace pm {

constexpr int kDoubleDigits = 17;
constexpr int kFloatDigits = 9;

/// Appends v with `digits` significant digits, the text of printf's %.*g
/// (std::to_chars' general format with a precision is defined as that, and
/// costs a quarter of the time: the ASCII PLY of frog5's interfaces).
inline void append_number(std::string& out, double v, int digits = kDoubleDigits) {
  char b[40];
  const std::to_chars_result r = std::to_chars(b, b + sizeof b, v, std::chars_format::general, digits);
  out.append(b, r.ptr);
}

/// v with `digits` significant digits (%.*g).
inline std::string number_text(double v, int digits = kDoubleDigits) {
  std::string s;
  append_number(s, v, digits);
  return s;
}

}  // namespace pm

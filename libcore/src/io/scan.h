#pragma once
// Internal to libcore/src/io: a cursor over a whole file in memory for the
// tetrahedral mesh readers (gmsh.cpp, vtk.cpp). ASCII words and numbers,
// binary values of either byte order, bounds checked: every read past the end
// throws InputError "<where>: line L: <what>: unexpected end of file
// (truncated?)", so readers need no checks of their own for truncation.
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"

namespace pm::scan {

/// The bytes of `path`. \throw IoError when it cannot be read.
inline std::string slurp(const std::string& path, const std::string& where) {
  require_readable(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(where + ": cannot open");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw IoError(where + ": read failed");
  return s.str();
}

class Cursor {
 public:
  Cursor(const std::string& data, std::string where) : d_(data), where_(std::move(where)) {}

  /// InputError "<where>: line L: <what>" (L: the line of the cursor).
  InputError error(const std::string& what) const {
    std::size_t line = 1;
    for (std::size_t i = 0; i < p_ && i < d_.size(); ++i) line += d_[i] == '\n';
    return InputError(where_ + ": line " + std::to_string(line) + ": " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { throw error(what); }

  std::size_t pos() const { return p_; }
  void seek(std::size_t p) { p_ = std::min(p, d_.size()); }
  std::size_t remaining() const { return d_.size() - p_; }
  bool at_end() {
    skip_space();
    return p_ >= d_.size();
  }
  void skip_space() {
    while (p_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
  }
  /// Next whitespace-separated word ("" at the end of the file).
  std::string word() {
    skip_space();
    const std::size_t b = p_;
    while (p_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
    return d_.substr(b, p_ - b);
  }
  /// The rest of the current line without its end; moves past the newline.
  std::string line() {
    std::size_t e = d_.find('\n', p_);
    if (e == std::string::npos) e = d_.size();
    std::string l = d_.substr(p_, e - p_);
    while (!l.empty() && (l.back() == '\r' || l.back() == ' ' || l.back() == '\t')) l.pop_back();
    p_ = std::min(d_.size(), e + 1);
    return l;
  }
  /// Skip to the start of the next line.
  void next_line() {
    while (p_ < d_.size() && d_[p_] != '\n') ++p_;
    if (p_ < d_.size()) ++p_;
  }

  /// An ASCII number (strtod syntax, also nan/inf; those are the caller's to refuse).
  double number(const std::string& what) {
    skip_space();
    if (p_ >= d_.size()) fail(what + ": unexpected end of file (truncated?)");
    const std::size_t b = p_;
    while (p_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
    const std::string w = d_.substr(b, p_ - b);
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    if (w.empty() || *end != '\0') {
      p_ = b;
      fail(what + ": " + quote(w.substr(0, 24)) + " is not a number");
    }
    return v;
  }
  /// An ASCII integer in [lo, hi].
  long long integer(const std::string& what, long long lo, long long hi) {
    const double v = number(what);
    if (!(v >= double(lo) && v <= double(hi)) || v != std::floor(v))
      fail(what + ": " + format_number(v) + " is out of range; expected an integer in [" + std::to_string(lo) +
           ", " + std::to_string(hi) + "]");
    return (long long)v;
  }
  /// A finite ASCII number.
  double finite(const std::string& what) {
    const double v = number(what);
    if (!std::isfinite(v)) fail(what + ": " + format_number(v) + "; expected a finite number");
    return v;
  }

  /// `n` raw bytes.
  const char* bytes(std::size_t n, const std::string& what) {
    if (remaining() < n) fail(what + ": unexpected end of binary data (truncated?)");
    const char* b = d_.data() + p_;
    p_ += n;
    return b;
  }
  /// An unsigned binary integer of `size` bytes (1, 2, 4 or 8).
  std::uint64_t uint(int size, bool big_endian, const std::string& what) {
    const unsigned char* b = reinterpret_cast<const unsigned char*>(bytes(std::size_t(size), what));
    std::uint64_t u = 0;
    for (int k = 0; k < size; ++k) u |= std::uint64_t(b[big_endian ? size - 1 - k : k]) << (8 * k);
    return u;
  }
  std::int64_t sint(int size, bool big_endian, const std::string& what) {
    const std::uint64_t u = uint(size, big_endian, what);
    if (size == 8) return std::int64_t(u);
    const std::uint64_t sign = std::uint64_t(1) << (8 * size - 1);
    return std::int64_t(u ^ sign) - std::int64_t(sign);
  }
  double f64(bool big_endian, const std::string& what) {
    const std::uint64_t u = uint(8, big_endian, what);
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  double f32(bool big_endian, const std::string& what) {
    const std::uint32_t u = std::uint32_t(uint(4, big_endian, what));
    float v;
    std::memcpy(&v, &u, 4);
    return v;
  }
  /// True (and moves past it) when the next word is `w`.
  bool accept(const std::string& w) {
    const std::size_t b = p_;
    if (word() == w) return true;
    p_ = b;
    return false;
  }

 private:
  const std::string& d_;
  std::string where_;
  std::size_t p_ = 0;
};

}  // namespace pm::scan

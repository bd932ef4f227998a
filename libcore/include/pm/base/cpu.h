#pragma once
// What the CPU can do, asked once at run time. The library is built for
// baseline x86-64; a few hot loops have an AVX2 copy chosen by this.

namespace pm {

/// True when the CPU runs AVX2 and the library was built with its AVX2
/// copies (GCC or Clang on x86-64 without PM_NO_AVX2).
bool cpu_has_avx2();

}  // namespace pm

#pragma once
// What the CPU can do, asked once at run time. The library is built for
// baseline x86-64; a few hot loops have an AVX2 copy chosen by this.

// Whether this build carries the AVX2 copies (function target attributes:
// GCC or Clang on x86-64, unless PM_NO_AVX2 is defined). Files with AVX2
// copies include <immintrin.h> under it.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(PM_NO_AVX2)
#define PM_AVX2_COPIES 1
#else
#define PM_AVX2_COPIES 0
#endif

namespace pm {

/// True when the CPU runs AVX2 and the library was built with its AVX2
/// copies (PM_AVX2_COPIES).
bool cpu_has_avx2();

}  // namespace pm

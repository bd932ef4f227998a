#include "pm/base/cpu.h"

namespace pm {

#if defined(__GNUC__) && defined(__x86_64__) && !defined(PM_NO_AVX2)
bool cpu_has_avx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}
#else
bool cpu_has_avx2() { return false; }
#endif

}  // namespace pm

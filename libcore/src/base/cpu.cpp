#include "pm/base/cpu.h"

namespace pm {

#if PM_AVX2_COPIES
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

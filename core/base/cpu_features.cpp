#include "core/base/cpu_features.h"

namespace st {

bool cpu_has_avx512f() {
#if ST_HAVE_AVX512
  static const bool available = __builtin_cpu_supports("avx512f");
  return available;
#else
  return false;
#endif
}

bool cpu_has_popcnt() {
#if ST_HAVE_POPCNT
  static const bool available = __builtin_cpu_supports("popcnt");
  return available;
#else
  return false;
#endif
}

}  // namespace st

// Run-time CPU features, for kernels that are compiled in alongside their
// portable forms with a per-function target attribute and chosen at run
// time (the rest of the build keeps its instruction set). Each such kernel
// gives the same bits as its portable form.
#pragma once

// The AVX-512 and POPCNT forms: x86-64 with GCC or Clang.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_HAVE_AVX512 1
#define ST_AVX512 __attribute__((target("avx512f")))
#define ST_HAVE_POPCNT 1
#define ST_POPCNT __attribute__((target("popcnt")))
#else
#define ST_HAVE_AVX512 0
#define ST_HAVE_POPCNT 0
#endif

namespace st {

// True if this build has AVX-512 forms (ST_HAVE_AVX512) and the CPU and OS
// it runs on support AVX-512F. Asked once, then cached.
bool cpu_has_avx512f();
// True if this build has POPCNT forms (ST_HAVE_POPCNT) and the CPU has the
// POPCNT instruction. Asked once, then cached.
bool cpu_has_popcnt();

}  // namespace st

// What the processor can run, for the few loops compiled twice: once for the baseline and once
// with __attribute__((target("avx2"))), the second called only where this says so.
#pragma once

namespace placerec {

// Whether the processor runs AVX2 instructions (checked once).
inline bool CpuHasAvx2() {
#if defined(__x86_64__)
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

}  // namespace placerec

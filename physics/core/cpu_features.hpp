// Which instruction sets the CPU running incise has, asked once. The kernels with an AVX2 path
// (block_product, element_assembly, rotation_extraction) are compiled for it with a target
// attribute and chosen at run time, so one binary runs on any x86-64.
#pragma once

namespace incise::physics {

inline bool cpu_has_avx2() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

inline bool cpu_has_fma() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool has = __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

inline bool cpu_has_f16c() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool has = __builtin_cpu_supports("avx") && __builtin_cpu_supports("f16c");
  return has;
#else
  return false;
#endif
}

}  // namespace incise::physics

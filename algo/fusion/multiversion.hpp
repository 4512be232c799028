// The few per-voxel loops of fusion that are worth a second build for wider vectors: on x86-64
// with GCC or Clang, FB_TARGET_X86_64_V3 compiles a function for x86-64-v3 (AVX2, FMA) and
// cpu_has_x86_64_v3() tells at run time whether this CPU may call it. Elsewhere (arm64: NEON is
// the baseline) FB_HAVE_X86_64_V3 is 0 and only the baseline build exists. Only the marked
// functions change instruction set, so inline code they share with the rest of the program
// (Eigen) keeps one instruction set per emitted symbol.
#pragma once

// -DFB_NO_X86_MULTIVERSION builds only the baseline paths (the device's: 4 lanes, no clones).
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && \
    !defined(FB_NO_X86_MULTIVERSION)
#define FB_HAVE_X86_64_V3 1
#define FB_TARGET_X86_64_V3 __attribute__((target("arch=x86-64-v3")))
#else
#define FB_HAVE_X86_64_V3 0
#define FB_TARGET_X86_64_V3
#endif

// FB_CLONE_X86_64_V3 builds a whole function twice, for the baseline and for x86-64-v3, and the
// loader picks the one this CPU runs (an ifunc; GCC only, not under the sanitizers). Lambdas in
// it are only in the clone when inlined (mark them FB_INLINE).
// FB_CLONE_X86_64_V2 does the same for x86-64-v2 (SSE4.1: the 32-bit multiplies, blends and
// narrowing conversions that 4-lane code needs and that NEON has too).
#if FB_HAVE_X86_64_V3 && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define FB_CLONE_X86_64_V3 __attribute__((target_clones("default", "arch=x86-64-v3")))
#define FB_CLONE_X86_64_V2 __attribute__((target_clones("default", "arch=x86-64-v2")))
#else
#define FB_CLONE_X86_64_V3
#define FB_CLONE_X86_64_V2
#endif
#define FB_INLINE __attribute__((always_inline))

namespace fb {

#if FB_HAVE_X86_64_V3
inline bool cpu_has_x86_64_v3() {
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
         __builtin_cpu_supports("bmi2");
}
#endif

}  // namespace fb

#pragma once
// Attributes for the hot loops that GCC vectorises. Private to libseg (never installed).

// LOBE_VECTOR_CLONES compiles a function twice on x86-64 with GCC, for the baseline (SSE2, 4
// floats a vector) and for AVX2 (8), and picks one at load time from the CPU. AVX2 without FMA:
// no product is fused into a sum, so both clones compute the same bits.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define LOBE_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LOBE_VECTOR_CLONES
#endif

// A loop body split into a function vectorises only if the function is inlined into it.
#if defined(__GNUC__)
#define LOBE_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define LOBE_ALWAYS_INLINE inline
#endif

// Per-instruction-set clones of hot loops. The library is built for baseline x86-64
// (SSE2); GCC also builds AVX2 and AVX-512 clones of a function marked NBTF_SIMD_CLONES and
// picks one at load time by CPU feature (not model), so newer CPUs get the wide clone. The
// loops stay plain C++ that the compiler vectorizes for each target. Off under clang and
// the sanitizers, whose runtimes do not support ifunc resolvers well.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define NBTF_SIMD_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
// Code that only pays with 16-float registers (it keeps many 16-float vectors live, which on
// narrower targets spill): built for AVX-512 alone, called only where hasAvx512().
#define NBTF_AVX512 __attribute__((target("avx512f")))
inline bool hasAvx512() { return __builtin_cpu_supports("avx512f"); }
#else
#define NBTF_SIMD_CLONES
#define NBTF_AVX512
inline bool hasAvx512() { return false; }
#endif

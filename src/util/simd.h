// SIMD support shared by the training kernels (model/) and the decoder (codec/): the CPU
// feature queries, cache-line aligned float buffers, and per-instruction-set clones.
//
// Two ways to pick a kernel by CPU, one feature query: training's loops are cloned
// automatically (below); the decoder builds explicit kernel sets (codec/decoder_kernels.h)
// because users choose one (`nbtf query --isa`) and the tests run every set on one machine.
//
// Per-instruction-set clones of hot loops. The library is built for baseline x86-64
// (SSE2); GCC also builds AVX2 and AVX-512 clones of a function marked NBTF_SIMD_CLONES and
// picks one at load time by CPU feature (not model), so newer CPUs get the wide clone. The
// loops stay plain C++ that the compiler vectorizes for each target. Off under clang and
// the sanitizers, whose runtimes do not support ifunc resolvers well.
#pragma once
#include <cstddef>
#include <new>
#include <vector>


#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define NBTF_SIMD_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
// Code that only pays with 16-float registers (it keeps many 16-float vectors live, which on
// narrower targets spill): built for AVX-512 alone, called only where hasAvx512().
#define NBTF_AVX512 __attribute__((target("avx512f")))
// The same for 8-float registers: AVX2 with FMA, called only where hasAvx2Fma().
#define NBTF_AVX2_FMA __attribute__((target("avx2,fma")))
// 8-float registers without FMA, for loops whose bits must match the baseline build's.
#define NBTF_AVX __attribute__((target("avx")))
inline bool hasAvx() { return __builtin_cpu_supports("avx"); }
inline bool hasAvx512() { return __builtin_cpu_supports("avx512f"); }
inline bool hasAvx512Vl() { return hasAvx512() && __builtin_cpu_supports("avx512vl"); }
inline bool hasAvx2Fma() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"); }
#else
#define NBTF_SIMD_CLONES
#define NBTF_AVX512
#define NBTF_AVX2_FMA
#define NBTF_AVX
inline bool hasAvx() { return false; }
inline bool hasAvx512() { return false; }
inline bool hasAvx512Vl() { return false; }
inline bool hasAvx2Fma() { return false; }
#endif

namespace nbtf {

// Cache-line aligned storage: a 64-byte vector load that straddles two lines costs two, and
// a kernel row that starts on a line never does.
template <class T> struct CacheAligned {
  using value_type = T;
  static constexpr std::align_val_t kAlign{64};
  CacheAligned() = default;
  template <class U> CacheAligned(const CacheAligned<U>&) {}
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlign)); }
  void deallocate(T* p, std::size_t) { ::operator delete(p, kAlign); }
  template <class U> bool operator==(const CacheAligned<U>&) const { return true; }
  template <class U> bool operator!=(const CacheAligned<U>&) const { return false; }
};
using AlignedFloats = std::vector<float, CacheAligned<float>>;

}  // namespace nbtf

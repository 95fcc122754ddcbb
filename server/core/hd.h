// CINEVOL_HD marks functions that run on both host and device: per-pixel and
// per-sample code lives in headers with this mark so the CPU and CUDA backends
// share one source.
#pragma once

#include <cmath>

#if defined(__CUDACC__)
#define CINEVOL_HD __host__ __device__ __forceinline__
#else
#define CINEVOL_HD inline
#endif

// As CINEVOL_HD, but kept out of line on the device: for a path the kernels
// rarely or never take, whose code would otherwise be copied into every hot
// loop that calls it (longer loops, more instruction-cache misses).
#if defined(__CUDACC__)
#define CINEVOL_HD_COLD __host__ __device__ __noinline__
#else
#define CINEVOL_HD_COLD inline
#endif

// True in nvcc's device pass only (inside a CINEVOL_HD body).
#if defined(__CUDA_ARCH__)
#define CINEVOL_DEVICE_PASS 1
#else
#define CINEVOL_DEVICE_PASS 0
#endif

// Unrolls the loop that follows in nvcc's device pass (GCC's -Wall would
// warn of the pragma).
#if CINEVOL_DEVICE_PASS
#define CINEVOL_UNROLL _Pragma("unroll")
#else
#define CINEVOL_UNROLL
#endif

// 2^x as the GPU's special function unit gives it (ex2.approx.ftz: within
// 2^-22 relative, results below 2^-126 flushed to 0), in one instruction
// where exp2f also scales subnormals; exp2f on the host.
CINEVOL_HD float FastExp2(float x) {
#if CINEVOL_DEVICE_PASS
  float r;
  asm("ex2.approx.ftz.f32 %0, %1;" : "=f"(r) : "f"(x));
  return r;
#else
  return exp2f(x);
#endif
}

// log2(x) as the GPU's special function unit gives it (lg2.approx.ftz:
// within 2^-22 absolute for x in [0.5, 2], subnormal x flushed to 0, giving
// -inf), in one instruction where logf takes about twenty; log2f on the host.
CINEVOL_HD float FastLog2(float x) {
#if CINEVOL_DEVICE_PASS
  float r;
  asm("lg2.approx.ftz.f32 %0, %1;" : "=f"(r) : "f"(x));
  return r;
#else
  return log2f(x);
#endif
}

// Loads through the read-only data cache on the GPU; a plain load elsewhere.
template <class T>
CINEVOL_HD T LoadReadOnly(const T* p) {
#if CINEVOL_DEVICE_PASS
  if constexpr (sizeof(T) == 16 && alignof(T) == 16) {
    const float4 v = __ldg(reinterpret_cast<const float4*>(p));
    return T{v.x, v.y, v.z, v.w};
  } else {
    return __ldg(p);
  }
#else
  return *p;
#endif
}

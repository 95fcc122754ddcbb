// CINEVOL_HD marks functions that run on both host and device: per-pixel and
// per-sample code lives in headers with this mark so the CPU and CUDA backends
// share one source.
#pragma once

#if defined(__CUDACC__)
#define CINEVOL_HD __host__ __device__ __forceinline__
#else
#define CINEVOL_HD inline
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

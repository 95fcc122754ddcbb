// CINEVOL_HD marks functions that run on both host and device: per-pixel and
// per-sample code lives in headers with this mark so the CPU and CUDA backends
// share one source.
#pragma once

#if defined(__CUDACC__)
#define CINEVOL_HD __host__ __device__ __forceinline__
#define CINEVOL_DEVICE_CODE 1
#else
#define CINEVOL_HD inline
#define CINEVOL_DEVICE_CODE 0
#endif

// The part of nvJPEG's C API the frame encoder calls, declared here because
// the build machines have no nvjpeg.h: the library is found at run time
// (nvjpeg_library.h). Values as NVIDIA's nvjpeg.h gives them (CUDA 10 to 13).
#pragma once

#include <cstddef>

extern "C" {

struct nvjpegHandle;
struct nvjpegEncoderState;
struct nvjpegEncoderParams;
struct CUstream_st;  // what cudaStream_t points to

using nvjpegHandle_t = nvjpegHandle*;
using nvjpegEncoderState_t = nvjpegEncoderState*;
using nvjpegEncoderParams_t = nvjpegEncoderParams*;
using NvjpegStream = CUstream_st*;  // the same type as cudaStream_t

enum nvjpegStatus_t : int { NVJPEG_STATUS_SUCCESS = 0 };

enum nvjpegChromaSubsampling_t : int { NVJPEG_CSS_444 = 0, NVJPEG_CSS_422 = 1, NVJPEG_CSS_420 = 2 };

// libraryPropertyType (library_types.h), for nvjpegGetProperty.
enum NvjpegProperty : int { kNvjpegMajorVersion = 0, kNvjpegMinorVersion = 1, kNvjpegPatchLevel = 2 };

constexpr int NVJPEG_MAX_COMPONENT = 4;

// Planes in device memory: Y, Cb, Cr for nvjpegEncodeYUV, each with its pitch in bytes.
struct nvjpegImage_t {
  unsigned char* channel[NVJPEG_MAX_COMPONENT];
  std::size_t pitch[NVJPEG_MAX_COMPONENT];
};

using NvjpegGetPropertyFn = nvjpegStatus_t (*)(int type, int* value);
using NvjpegCreateSimpleFn = nvjpegStatus_t (*)(nvjpegHandle_t* handle);
using NvjpegDestroyFn = nvjpegStatus_t (*)(nvjpegHandle_t handle);
using NvjpegEncoderStateCreateFn = nvjpegStatus_t (*)(nvjpegHandle_t handle, nvjpegEncoderState_t* state,
                                                      NvjpegStream stream);
using NvjpegEncoderStateDestroyFn = nvjpegStatus_t (*)(nvjpegEncoderState_t state);
using NvjpegEncoderParamsCreateFn = nvjpegStatus_t (*)(nvjpegHandle_t handle, nvjpegEncoderParams_t* params,
                                                       NvjpegStream stream);
using NvjpegEncoderParamsDestroyFn = nvjpegStatus_t (*)(nvjpegEncoderParams_t params);
using NvjpegEncoderParamsSetQualityFn = nvjpegStatus_t (*)(nvjpegEncoderParams_t params, int quality,
                                                           NvjpegStream stream);
using NvjpegEncoderParamsSetSamplingFactorsFn = nvjpegStatus_t (*)(nvjpegEncoderParams_t params,
                                                                   nvjpegChromaSubsampling_t chroma,
                                                                   NvjpegStream stream);
using NvjpegEncodeYuvFn = nvjpegStatus_t (*)(nvjpegHandle_t handle, nvjpegEncoderState_t state,
                                             nvjpegEncoderParams_t params, const nvjpegImage_t* source,
                                             nvjpegChromaSubsampling_t chroma, int width, int height,
                                             NvjpegStream stream);
// data == nullptr: only the length; else copies the bitstream and waits for it.
using NvjpegEncodeRetrieveBitstreamFn = nvjpegStatus_t (*)(nvjpegHandle_t handle, nvjpegEncoderState_t state,
                                                           unsigned char* data, std::size_t* length,
                                                           NvjpegStream stream);

}  // extern "C"

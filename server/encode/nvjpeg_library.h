// nvJPEG, loaded at run time where the machine's CUDA has it: the build
// needs neither its header nor its library, and a server without it encodes
// frames on the CPU as before (pipeline/jpeg_encoder.h chooses).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "encode/nvjpeg_api.h"

namespace cinevol {

// The entry points the frame encoder calls, resolved by dlsym; the library
// stays loaded for the process's life.
struct NvjpegLibrary {
  std::string name;  // the soname or path dlopen took
  int major = 0, minor = 0, patch = 0;
  NvjpegCreateSimpleFn create_simple = nullptr;
  NvjpegDestroyFn destroy = nullptr;
  NvjpegEncoderStateCreateFn encoder_state_create = nullptr;
  NvjpegEncoderStateDestroyFn encoder_state_destroy = nullptr;
  NvjpegEncoderParamsCreateFn encoder_params_create = nullptr;
  NvjpegEncoderParamsDestroyFn encoder_params_destroy = nullptr;
  NvjpegEncoderParamsSetQualityFn encoder_params_set_quality = nullptr;
  NvjpegEncoderParamsSetSamplingFactorsFn encoder_params_set_sampling_factors = nullptr;
  NvjpegEncodeYuvFn encode_yuv = nullptr;
  NvjpegEncodeRetrieveBitstreamFn encode_retrieve_bitstream = nullptr;
};

// What a search found: the library, or why there is none.
struct NvjpegLookup {
  std::shared_ptr<const NvjpegLibrary> library;
  std::string why_not;  // empty where library is set
};

// Where nvJPEG is looked for, in order: its sonames as the loader finds them
// (LD_LIBRARY_PATH, the ld.so cache), newest first, then the same under
// CUDA's usual folders, which are often not on the loader's path.
std::vector<std::string> NvjpegCandidates();

// The first candidate that loads and has every entry point. Never throws:
// a miss says what was tried and what failed.
NvjpegLookup FindNvjpeg(const std::vector<std::string>& candidates = NvjpegCandidates());

}  // namespace cinevol

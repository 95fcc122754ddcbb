// The encoder choice, made once per process, and the nvJPEG search's log line.
#include "pipeline/jpeg_encoder.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"

namespace cinevol {
namespace {

// Empty where nvJPEG can encode `backend`'s frames; else the reason.
std::string WhyNoNvjpeg(Backend backend, const NvjpegLookup& nvjpeg) {
  if (!nvjpeg.library) return nvjpeg.why_not;
  if (backend != Backend::kCuda) return "frames render on the CPU, and nvJPEG encodes only frames a GPU renders";
#if CINEVOL_WITH_CUDA
  try {
    MakeNvjpegEncoder(nvjpeg.library);  // a handle and an encoder state on this GPU, then freed
  } catch (const std::exception& e) {
    return fmt::format("{} loads but does not start on this GPU: {}", nvjpeg.library->name, e.what());
  }
  return {};
#else
  return "this build has no CUDA";
#endif
}

}  // namespace

JpegEncoderKind ParseJpegEncoder(std::string_view name) {
  if (name == "auto") return JpegEncoderKind::kAuto;
  if (name == "cpu") return JpegEncoderKind::kCpu;
  if (name == "cuda") return JpegEncoderKind::kCuda;
  if (name == "nvjpeg") return JpegEncoderKind::kNvjpeg;
  throw InputError(fmt::format("--jpeg-encoder: '{}' is not auto, cpu, cuda or nvjpeg", name));
}

const char* ToString(JpegEncoderKind kind) {
  switch (kind) {
    case JpegEncoderKind::kAuto:
      return "auto";
    case JpegEncoderKind::kCpu:
      return "cpu";
    case JpegEncoderKind::kCuda:
      return "cuda";
    case JpegEncoderKind::kNvjpeg:
      return "nvjpeg";
  }
  return "?";
}

const NvjpegLookup& ProcessNvjpeg() {
  static const NvjpegLookup lookup = [] {
    NvjpegLookup found = FindNvjpeg();
    if (found.library) {
      const NvjpegLibrary& lib = *found.library;
      spdlog::info("nvJPEG: found {} (version {}.{}.{})", lib.name, lib.major, lib.minor, lib.patch);
    } else {
      spdlog::info("nvJPEG: {}", found.why_not);
    }
    return found;
  }();
  return lookup;
}

JpegEncoderKind ChooseJpegEncoder(JpegEncoderKind requested, Backend backend, const NvjpegLookup& nvjpeg) {
  if (requested == JpegEncoderKind::kCpu || (requested == JpegEncoderKind::kAuto && backend != Backend::kCuda)) {
    spdlog::info("JPEG encoder: cpu (libjpeg-turbo, in bands){}",
                 requested == JpegEncoderKind::kCpu ? ", as --jpeg-encoder asks" : ": frames render on the CPU");
    return JpegEncoderKind::kCpu;
  }
  if (requested != JpegEncoderKind::kNvjpeg) {  // auto or cuda
    if (backend != Backend::kCuda) throw InputError("--jpeg-encoder cuda: frames render on the CPU");
    spdlog::info("JPEG encoder: cuda (cinevol's coder on the GPU that renders each frame)");
    return JpegEncoderKind::kCuda;
  }
  const std::string why_not = WhyNoNvjpeg(backend, nvjpeg);
  if (!why_not.empty()) throw InputError("--jpeg-encoder nvjpeg: " + why_not);
  spdlog::info("JPEG encoder: nvjpeg ({}) on the GPU that renders each frame", nvjpeg.library->name);
  return JpegEncoderKind::kNvjpeg;
}

}  // namespace cinevol

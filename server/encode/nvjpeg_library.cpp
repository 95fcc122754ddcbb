// dlopen and dlsym for nvJPEG's entry points.
#include "encode/nvjpeg_library.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstring>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace cinevol {
namespace {

// CUDA 13, 12 and 11 builds; the plain name where only the toolkit's
// development link exists.
constexpr const char* kSonames[] = {"libnvjpeg.so.13", "libnvjpeg.so.12", "libnvjpeg.so.11", "libnvjpeg.so"};
constexpr const char* kCudaFolders[] = {"/usr/local/cuda/lib64", "/usr/local/cuda/targets/x86_64-linux/lib",
                                        "/usr/local/cuda/targets/sbsa-linux/lib", "/usr/lib/x86_64-linux-gnu"};

struct DlCloser {
  void operator()(void* handle) const { dlclose(handle); }
};
using DlHandle = std::unique_ptr<void, DlCloser>;

// Resolves `symbol` into `fn`; false (and `missing` set) where absent.
template <class Fn>
bool Resolve(void* handle, const char* symbol, Fn& fn, std::string& missing) {
  fn = reinterpret_cast<Fn>(dlsym(handle, symbol));
  if (!fn) missing = symbol;
  return fn != nullptr;
}

bool ResolveAll(void* handle, NvjpegLibrary& lib, std::string& missing) {
  return Resolve(handle, "nvjpegCreateSimple", lib.create_simple, missing) &&
         Resolve(handle, "nvjpegDestroy", lib.destroy, missing) &&
         Resolve(handle, "nvjpegEncoderStateCreate", lib.encoder_state_create, missing) &&
         Resolve(handle, "nvjpegEncoderStateDestroy", lib.encoder_state_destroy, missing) &&
         Resolve(handle, "nvjpegEncoderParamsCreate", lib.encoder_params_create, missing) &&
         Resolve(handle, "nvjpegEncoderParamsDestroy", lib.encoder_params_destroy, missing) &&
         Resolve(handle, "nvjpegEncoderParamsSetQuality", lib.encoder_params_set_quality, missing) &&
         Resolve(handle, "nvjpegEncoderParamsSetSamplingFactors", lib.encoder_params_set_sampling_factors, missing) &&
         Resolve(handle, "nvjpegEncodeYUV", lib.encode_yuv, missing) &&
         Resolve(handle, "nvjpegEncodeRetrieveBitstream", lib.encode_retrieve_bitstream, missing);
}

// The version, for the log line; a library without nvjpegGetProperty keeps 0.0.0.
void ReadVersion(void* handle, NvjpegLibrary& lib) {
  auto get = reinterpret_cast<NvjpegGetPropertyFn>(dlsym(handle, "nvjpegGetProperty"));
  if (!get) return;
  get(kNvjpegMajorVersion, &lib.major);
  get(kNvjpegMinorVersion, &lib.minor);
  get(kNvjpegPatchLevel, &lib.patch);
}

// "none of A, B loads from the loader's path, /x, /y": the candidates'
// names and folders, each once, in order.
std::string NoneLoads(const std::vector<std::string>& candidates) {
  std::vector<std::string> names, folders;
  auto add = [](std::vector<std::string>& list, std::string item) {
    if (std::find(list.begin(), list.end(), item) == list.end()) list.push_back(std::move(item));
  };
  for (const std::string& candidate : candidates) {
    const std::size_t slash = candidate.rfind('/');
    add(names, slash == std::string::npos ? candidate : candidate.substr(slash + 1));
    add(folders, slash == std::string::npos ? "the loader's path" : candidate.substr(0, slash));
  }
  return fmt::format("none of {} loads from {}", fmt::join(names, ", "), fmt::join(folders, ", "));
}

}  // namespace

std::vector<std::string> NvjpegCandidates() {
  std::vector<std::string> names(std::begin(kSonames), std::end(kSonames));
  for (const char* folder : kCudaFolders) {
    for (const char* soname : kSonames) names.push_back(fmt::format("{}/{}", folder, soname));
  }
  return names;
}

NvjpegLookup FindNvjpeg(const std::vector<std::string>& candidates) {
  std::string tried;
  for (const std::string& name : candidates) {
    DlHandle handle(dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL));
    if (!handle) {
      // Absent is the common case; anything else (a dependency missing, a
      // wrong architecture) is worth saying.
      const char* error = dlerror();
      if (error && !std::strstr(error, "No such file")) tried += fmt::format("{}{}", tried.empty() ? "" : "; ", error);
      continue;
    }
    auto lib = std::make_shared<NvjpegLibrary>();
    std::string missing;
    if (!ResolveAll(handle.get(), *lib, missing)) {
      tried += fmt::format("{}{} lacks {}", tried.empty() ? "" : "; ", name, missing);
      continue;
    }
    lib->name = name;
    ReadVersion(handle.get(), *lib);
    (void)handle.release();  // the entry points stay valid for the process's life
    return {std::move(lib), {}};
  }
  const std::string none = NoneLoads(candidates);
  return {nullptr, "libnvjpeg not found: " + (tried.empty() ? none : tried + "; " + none)};
}

}  // namespace cinevol

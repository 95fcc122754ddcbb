// Choosing a denoiser and its backend.
#include "denoise/denoiser.h"

#include <fmt/format.h>

#include "core/error.h"

namespace cinevol {

std::unique_ptr<Denoiser> MakeCpuDenoiser(const DenoiserSettings& settings);
#if CINEVOL_WITH_CUDA
std::unique_ptr<Denoiser> MakeCudaDenoiser(const DenoiserSettings& settings);
#endif

namespace {

struct MethodName {
  DenoiseMethod method;
  const char* name;
};

constexpr MethodName kMethods[] = {{DenoiseMethod::kNone, "none"},        {DenoiseMethod::kAccumulate, "accumulate"},
                                   {DenoiseMethod::kKnn, "knn"},          {DenoiseMethod::kGuidedFilter, "guided"},
                                   {DenoiseMethod::kSvgf, "svgf"},        {DenoiseMethod::kWrls, "wrls"}};

}  // namespace

DenoiseMethod ParseDenoiseMethod(std::string_view name) {
  for (const MethodName& m : kMethods) {
    if (name == m.name) return m.method;
  }
  throw InputError(fmt::format("unknown denoiser '{}': use none, accumulate, knn, guided, svgf or wrls", name));
}

const char* ToString(DenoiseMethod method) {
  for (const MethodName& m : kMethods) {
    if (method == m.method) return m.name;
  }
  return "?";
}

bool UsesSurfaceNormals(const DenoiserSettings& s) {
  return (s.method == DenoiseMethod::kWrls && s.wrls.atrous_normal_stop > 0.0f) ||
         (s.method == DenoiseMethod::kSvgf && s.svgf.normal_stop > 0.0f);
}

bool operator==(const WrlsSettings&, const WrlsSettings&) = default;
bool operator==(const KnnSettings&, const KnnSettings&) = default;
bool operator==(const GuidedFilterSettings&, const GuidedFilterSettings&) = default;
bool operator==(const SvgfSettings&, const SvgfSettings&) = default;
bool operator==(const DenoiserSettings&, const DenoiserSettings&) = default;

std::unique_ptr<Denoiser> CreateDenoiser(Backend backend, const DenoiserSettings& settings) {
#if CINEVOL_WITH_CUDA
  if (Resolve(backend, "denoiser") == Backend::kCuda) return MakeCudaDenoiser(settings);
#else
  Resolve(backend, "denoiser");  // throws for kCuda
#endif
  return MakeCpuDenoiser(settings);
}

}  // namespace cinevol

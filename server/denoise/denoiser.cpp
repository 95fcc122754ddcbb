// Choosing a denoiser and its backend.
#include "denoise/denoiser.h"

#include <tuple>

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

bool operator==(const DenoiserSettings& a, const DenoiserSettings& b) {
  const auto wrls = [](const WrlsSettings& s) {
    return std::tie(s.alpha, s.bandwidth, s.lambda, s.initial_p, s.max_trace_p, s.max_coefficient, s.firefly_clamp,
                    s.max_still_frames, s.residual_rate, s.drift_sigma, s.young_variance, s.feature_rescale,
                    s.feature_rescale_sigma, s.atrous_iterations, s.atrous_sigma_luminance, s.atrous_sigma_depth,
                    s.stabilize_history, s.stabilize_clamp, s.stabilize_recenter);
  };
  const auto knn = [](const KnnSettings& s) { return std::tie(s.radius, s.strength, s.fade_frames); };
  const auto guided = [](const GuidedFilterSettings& s) {
    return std::tie(s.radius, s.epsilon_feature, s.epsilon_depth, s.alpha);
  };
  const auto svgf = [](const SvgfSettings& s) {
    return std::tie(s.color_alpha, s.moments_alpha, s.iterations, s.sigma_luminance, s.sigma_depth);
  };
  return a.method == b.method && a.demodulate == b.demodulate && wrls(a.wrls) == wrls(b.wrls) &&
         knn(a.knn) == knn(b.knn) && guided(a.guided) == guided(b.guided) && svgf(a.svgf) == svgf(b.svgf);
}

std::unique_ptr<Denoiser> CreateDenoiser(Backend backend, const DenoiserSettings& settings) {
#if CINEVOL_WITH_CUDA
  if (Resolve(backend, "denoiser") == Backend::kCuda) return MakeCudaDenoiser(settings);
#else
  Resolve(backend, "denoiser");  // throws for kCuda
#endif
  return MakeCpuDenoiser(settings);
}

}  // namespace cinevol

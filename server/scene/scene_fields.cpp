// The tables of the scene's numbers.
#include "scene/scene_fields.h"

#include <cmath>
#include <type_traits>

#include <fmt/format.h>

#include "scene/scene_file.h"

namespace cinevol {
namespace {

// The accessors of field `cpp` of Message: get, has (optional fields only), set.
#define CINEVOL_GET_SET(Message, cpp)                         \
  [](const Message& m) { return double(m.cpp()); }, nullptr,  \
      [](Message& m, double v) { m.set_##cpp(static_cast<std::decay_t<decltype(m.cpp())>>(v)); }
#define CINEVOL_OPTIONAL(Message, cpp)                                           \
  [](const Message& m) { return double(m.cpp()); }, [](const Message& m) { return m.has_##cpp(); }, \
      [](Message& m, double v) { m.set_##cpp(static_cast<std::decay_t<decltype(m.cpp())>>(v)); }

constexpr double kInf = INFINITY;

const NumberField<v1::Camera> kCamera[] = {
    {"fovYDeg", 1e-3, 170, false, "degrees", 30, "", CINEVOL_OPTIONAL(v1::Camera, fov_y_deg)},
    {"apertureMm", 0, kMaxSceneMm, false, "mm", {}, "", CINEVOL_GET_SET(v1::Camera, aperture_mm)},
    {"focalDistanceMm", 0, kMaxSceneMm, false, "mm", {}, "", CINEVOL_GET_SET(v1::Camera, focal_distance_mm)},
    {"exposure", -20, 20, false, "stops", {}, "", CINEVOL_GET_SET(v1::Camera, exposure)},
};

const NumberField<v1::RenderSettings> kRender[] = {
    {"width", 1, 8192, false, "pixels", 640, "--max-pixels", CINEVOL_OPTIONAL(v1::RenderSettings, width)},
    {"height", 1, 8192, false, "pixels", 480, "--max-pixels", CINEVOL_OPTIONAL(v1::RenderSettings, height)},
    {"spp", 1, 65536, false, "samples per pixel", 2, "--max-frame-spp, --max-frame-samples",
     CINEVOL_OPTIONAL(v1::RenderSettings, spp)},
    {"maxBounces", 0, 256, false, "scattering events", 4, "--max-bounces",
     CINEVOL_OPTIONAL(v1::RenderSettings, max_bounces)},
};

const NumberField<v1::TransferFunction> kTransferFunction[] = {
    {"densityScale", 0, 1e6, false, "per mm", 1, "", CINEVOL_OPTIONAL(v1::TransferFunction, density_scale)},
    {"gradientFactor", 0, kInf, false, "none", 1, "", CINEVOL_OPTIONAL(v1::TransferFunction, gradient_factor)},
    {"phaseG", -1, 1, true, "none", 0, "", CINEVOL_OPTIONAL(v1::TransferFunction, phase_g)},
};

#undef CINEVOL_GET_SET
#undef CINEVOL_OPTIONAL

template <class Message>
bool InRange(const NumberField<Message>& f, double v) {
  if (std::isnan(v)) return false;
  return f.open ? v > f.lo && v < f.hi : v >= f.lo && v <= f.hi && std::isfinite(v);
}

std::string Range(double lo, double hi, bool open) {
  return fmt::format("{}{:g}, {:g}{}", open ? "(" : "[", lo, hi, open || std::isinf(hi) ? ")" : "]");
}

template <class Message>
void AddRows(std::string& out, std::string_view message, std::span<const NumberField<Message>> fields) {
  for (const NumberField<Message>& f : fields) {
    out += fmt::format("| `{}.{}` | {} | {} | {} | {} |\n", message, f.name,
                       f.fallback ? fmt::format("{:g}", *f.fallback) : (f.has ? "unset" : "0"),
                       Range(f.lo, f.hi, f.open), f.unit, f.limit.empty() ? "" : fmt::format("`{}`", f.limit));
  }
}

}  // namespace

std::span<const NumberField<v1::Camera>> CameraNumbers() { return kCamera; }
std::span<const NumberField<v1::RenderSettings>> RenderNumbers() { return kRender; }
std::span<const NumberField<v1::TransferFunction>> TransferFunctionNumbers() { return kTransferFunction; }

template <class Message>
void CheckRanges(const Message& message, std::span<const NumberField<Message>> fields, const std::string& prefix,
                 std::vector<std::string>& problems) {
  for (const NumberField<Message>& f : fields) {
    const double v = f.get(message);
    if (!InRange(f, v)) problems.push_back(fmt::format("{}{}: {:g} is outside {}", prefix, f.name, v,
                                                       Range(f.lo, f.hi, f.open)));
  }
}

template void CheckRanges(const v1::Camera&, std::span<const NumberField<v1::Camera>>, const std::string&,
                          std::vector<std::string>&);
template void CheckRanges(const v1::RenderSettings&, std::span<const NumberField<v1::RenderSettings>>,
                          const std::string&, std::vector<std::string>&);
template void CheckRanges(const v1::TransferFunction&, std::span<const NumberField<v1::TransferFunction>>,
                          const std::string&, std::vector<std::string>&);

std::string SceneNumbersMarkdown() {
  std::string out = "| field | default | range | unit | bounded further by |\n| --- | --- | --- | --- | --- |\n";
  AddRows<v1::Camera>(out, "camera", kCamera);
  AddRows<v1::RenderSettings>(out, "render", kRender);
  AddRows<v1::TransferFunction>(out, "transferFunction", kTransferFunction);
  return out;
}

}  // namespace cinevol

// The preset tables. Values for CT follow the usual HU windows: lung
// parenchyma about -850, fat -100, soft tissue 20..60, contrast-filled vessels
// 200..500, bone 300..2000.
#include "io/presets.h"

#include <fmt/format.h>

#include "core/error.h"

namespace cinevol {
namespace {

struct Rgb {
  float r, g, b;
};

struct Point {
  float value, opacity;
  Rgb diffuse;
  float specular, roughness;
};

struct Preset {
  const char* name;
  bool relative;  // values are fractions of the volume's range (MR)
  float density_scale, gradient_factor;
  std::vector<Point> points;
};

const std::vector<Preset>& Presets() {
  constexpr Rgb kBone{0.92f, 0.88f, 0.78f}, kSkin{0.90f, 0.62f, 0.52f}, kFat{0.95f, 0.82f, 0.6f},
      kMuscle{0.78f, 0.32f, 0.28f}, kBlood{0.85f, 0.15f, 0.12f}, kLung{0.88f, 0.72f, 0.68f},
      kGrey{0.85f, 0.8f, 0.75f};
  static const std::vector<Preset> presets = {
      {"ct-bone", false, 2.0f, 2.0f,
       {{100, 0, kBone, 0, 0.5f}, {250, 0.3f, kBone, 0.15f, 0.5f}, {500, 1, kBone, 0.2f, 0.4f},
        {2000, 1, kBone, 0.2f, 0.4f}}},
      {"ct-soft-tissue", false, 0.5f, 1.5f,
       {{-300, 0, kFat, 0, 0.6f}, {-100, 0.02f, kFat, 0.05f, 0.6f}, {-20, 0.05f, kSkin, 0.1f, 0.5f},
        {40, 0.4f, kSkin, 0.1f, 0.5f}, {120, 0.4f, kMuscle, 0.1f, 0.5f},
        {250, 0.8f, kBone, 0.2f, 0.4f}, {1000, 1, kBone, 0.2f, 0.4f}}},
      {"ct-vessels", false, 2.0f, 1.5f,
       {{120, 0, kBlood, 0, 0.4f}, {220, 0.6f, kBlood, 0.3f, 0.3f}, {500, 1, kBlood, 0.3f, 0.3f},
        {700, 1, kBone, 0.2f, 0.4f}, {2000, 1, kBone, 0.2f, 0.4f}}},
      {"ct-lung", false, 1.0f, 1.0f,
       {{-1000, 0, kLung, 0, 0.6f}, {-900, 0, kLung, 0, 0.6f}, {-800, 0.04f, kLung, 0.05f, 0.6f},
        {-500, 0.08f, kLung, 0.05f, 0.6f}, {-300, 0, kLung, 0, 0.6f}, {0, 0, kBlood, 0, 0.5f},
        {150, 0.6f, kBlood, 0.2f, 0.4f}, {400, 0.9f, kBone, 0.2f, 0.4f}}},
      {"mr-default", true, 1.0f, 1.0f,
       {{0.08f, 0, kGrey, 0, 0.6f}, {0.2f, 0.05f, kGrey, 0.05f, 0.6f},
        {0.5f, 0.5f, kGrey, 0.1f, 0.5f}, {1.0f, 0.9f, kGrey, 0.1f, 0.5f}}},
  };
  return presets;
}

const Preset* Find(std::string_view name) {
  for (const Preset& p : Presets()) {
    if (name == p.name) return &p;
  }
  return nullptr;
}

void SetColor(v1::Color* c, Rgb rgb) {
  c->set_r(rgb.r);
  c->set_g(rgb.g);
  c->set_b(rgb.b);
}

}  // namespace

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const Preset& p : Presets()) names.emplace_back(p.name);
  return names;
}

bool IsPreset(std::string_view name) { return Find(name) != nullptr; }

v1::TransferFunction MakePreset(std::string_view name, float min_value, float max_value) {
  const Preset* preset = Find(name);
  if (!preset) {
    throw InputError(fmt::format("unknown transfer-function preset '{}': use {}", name,
                                 fmt::join(PresetNames(), ", ")));
  }
  v1::TransferFunction tf;
  tf.set_preset(preset->name);
  tf.set_density_scale(preset->density_scale);
  tf.set_gradient_factor(preset->gradient_factor);
  tf.set_phase_g(0.0f);
  const float range = max_value > min_value ? max_value - min_value : 1.0f;
  float previous = -INFINITY;
  for (const Point& p : preset->points) {
    auto* out = tf.add_points();
    float value = preset->relative ? min_value + p.value * range : p.value;
    // A degenerate range must still give strictly increasing points.
    value = std::max(value, std::nextafter(previous, INFINITY));
    previous = value;
    out->set_value(value);
    out->set_opacity(p.opacity);
    SetColor(out->mutable_diffuse(), p.diffuse);
    SetColor(out->mutable_specular(), {p.specular, p.specular, p.specular});
    out->set_roughness(p.roughness);
    SetColor(out->mutable_emission(), {0, 0, 0});
  }
  return tf;
}

v1::Scene MakePresetScene(std::string_view preset, Vec3f extent_mm) {
  if (!IsPreset(preset)) MakePreset(preset, 0, 1);  // throws, naming the presets
  v1::Scene scene;
  scene.mutable_transfer_function()->set_preset(std::string(preset));
  scene.mutable_camera()->set_view(v1::ANTERIOR);
  scene.mutable_camera()->set_fov_y_deg(30.0f);
  // The key light of examples/ct-bone.json, set for a 256 mm head: scaling
  // its position and size together keeps the irradiance it gives.
  const float s = Length(extent_mm) / Length(Vec3f{256, 256, 256});
  auto set = [s](v1::Vec3* v, float x, float y, float z) {
    v->set_x(x * s);
    v->set_y(y * s);
    v->set_z(z * s);
  };
  v1::AreaLight* key = scene.add_lights()->mutable_area();
  set(key->mutable_center(), -300, -400, 350);
  set(key->mutable_edge_u(), 70, 100, 150);
  set(key->mutable_edge_v(), 150, -110, 0);
  SetColor(key->mutable_color(), {1.0f, 0.95f, 0.9f});
  key->set_intensity(40);
  v1::EnvironmentLight* sky = scene.add_lights()->mutable_environment();
  SetColor(sky->mutable_gradient()->mutable_zenith(), {0.16f, 0.18f, 0.22f});
  SetColor(sky->mutable_gradient()->mutable_horizon(), {0.1f, 0.1f, 0.11f});
  SetColor(sky->mutable_gradient()->mutable_ground(), {0.03f, 0.03f, 0.03f});
  sky->set_intensity(1);
  return scene;
}

}  // namespace cinevol

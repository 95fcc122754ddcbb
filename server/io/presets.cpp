// Presets onto volumes, default presets by kind, and the preset scene.
#include "io/presets.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/error.h"
#include "io/scene_builder.h"
#include "io/volume_kind.h"

namespace cinevol {
namespace {

const PresetDefinition* Find(std::string_view name) {
  for (const PresetDefinition& p : PresetLibrary()) {
    if (name == p.name) return &p;
  }
  return nullptr;
}

void SetColor(v1::Color* c, PresetColor rgb) {
  c->set_r(rgb.r);
  c->set_g(rgb.g);
  c->set_b(rgb.b);
}

void SetVec(v1::Vec3* v, Vec3f p) {
  v->set_x(p.x);
  v->set_y(p.y);
  v->set_z(p.z);
}

// The extent of the volume's box along a world direction.
float ExtentAlong(const Volume& volume, Vec3f direction) {
  const Vec3f e = volume.extent_mm();
  return std::abs(direction.x) * e.x + std::abs(direction.y) * e.y + std::abs(direction.z) * e.z;
}

// Anterior, as radiologists start; but a thin stack of axial slices (a slab
// less than a quarter as deep as it is wide) is seen from above, not edge on.
v1::NamedView DefaultView(const Volume& volume) {
  const float superior = ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {0, 0, 1}));
  const float lateral = std::min(ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {1, 0, 0})),
                                 ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {0, 1, 0})));
  return superior < 0.25f * lateral ? v1::SUPERIOR : v1::ANTERIOR;
}

}  // namespace

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const PresetDefinition& p : PresetLibrary()) names.emplace_back(p.name);
  return names;
}

bool IsPreset(std::string_view name) { return Find(name) != nullptr; }

const PresetDefinition& FindPreset(std::string_view name) {
  const PresetDefinition* preset = Find(name);
  if (!preset) {
    throw InputError(fmt::format("unknown transfer-function preset '{}': use {}", name,
                                 fmt::join(PresetNames(), ", ")));
  }
  return *preset;
}

ValueWindow AutoWindow(const ValueHistogram& histogram) {
  ValueWindow w{histogram.OtsuThreshold(), 0};
  w.hi = histogram.Percentile(0.995, w.lo);
  // A constant volume's window is one unit wide, or where that is below the
  // value's precision, a millionth of the value (as its transfer table's).
  if (!(w.hi > w.lo)) w.hi = histogram.max_value > w.lo ? histogram.max_value : w.lo + std::max(1.0f, std::abs(w.lo) * 1e-6f);
  return w;
}

v1::TransferFunction MakePreset(std::string_view name, ValueWindow window) {
  const PresetDefinition& preset = FindPreset(name);
  v1::TransferFunction tf;
  tf.set_preset(preset.name);
  tf.set_density_scale(preset.density_scale);
  tf.set_gradient_factor(preset.gradient_factor);
  tf.set_phase_g(0.0f);
  const bool windowed = preset.scale == PresetScale::kWindow;
  float previous = -INFINITY;
  for (const PresetPoint& p : preset.points) {
    auto* out = tf.add_points();
    float value = windowed ? window.lo + p.value * (window.hi - window.lo) : p.value;
    // A degenerate window must still give strictly increasing points.
    value = std::max(value, std::nextafter(previous, INFINITY));
    previous = value;
    out->set_value(value);
    out->set_opacity(p.opacity);
    SetColor(out->mutable_diffuse(), p.diffuse);
    SetColor(out->mutable_specular(), {p.specular, p.specular, p.specular});
    out->set_roughness(p.roughness);
    SetColor(out->mutable_emission(), p.emission);
  }
  return tf;
}

std::string DefaultPreset(v1::VolumeKind kind) {
  switch (kind) {
    case v1::CT_HU: return "ct-bone";
    case v1::CT_SCALED: return "ct-auto";
    case v1::MR: return "mr-default";
    default: return "auto";
  }
}

std::string DefaultPreset(const Volume& volume) { return DefaultPreset(JudgeVolumeKind(volume).kind); }

v1::Scene MakePresetScene(std::string_view preset, const Volume& volume) {
  FindPreset(preset);  // throws, naming the presets
  v1::Scene scene;
  scene.mutable_transfer_function()->set_preset(std::string(preset));
  const v1::NamedView default_view = DefaultView(volume);
  scene.mutable_camera()->set_view(default_view);
  scene.mutable_camera()->set_fov_y_deg(30.0f);
  // The key light sits above the viewer's left and in front, at 2.75 times
  // the volume's bounding radius; its edges scale with that distance, so the
  // solid angle it fills, and the light it gives, are the same for any
  // volume (the light of examples/ct-bone.json on its 256 mm head).
  const ViewDirections view = NamedViewDirections(default_view, volume.metadata().direction);
  const Vec3f right = Normalize(Cross(-view.to_eye, view.up));
  const float radius = 0.5f * Length(volume.extent_mm());
  const Vec3f towards_light = Normalize(right * -0.55f + view.up * 0.6f + view.to_eye * 0.6f);
  const Vec3f edge_u = Normalize(Cross(towards_light, view.up)), edge_v = Cross(edge_u, towards_light);
  const float size = 0.86f * radius;  // front face, edge_u x edge_v, towards the volume
  v1::AreaLight* key = scene.add_lights()->mutable_area();
  SetVec(key->mutable_center(), towards_light * (2.75f * radius));
  SetVec(key->mutable_edge_u(), edge_u * size);
  SetVec(key->mutable_edge_v(), edge_v * size);
  SetColor(key->mutable_color(), {1.0f, 0.95f, 0.9f});
  key->set_intensity(40);
  v1::EnvironmentLight* sky = scene.add_lights()->mutable_environment();
  SetColor(sky->mutable_gradient()->mutable_zenith(), {0.16f, 0.18f, 0.22f});
  SetColor(sky->mutable_gradient()->mutable_horizon(), {0.1f, 0.1f, 0.11f});
  SetColor(sky->mutable_gradient()->mutable_ground(), {0.03f, 0.03f, 0.03f});
  SetVec(sky->mutable_gradient()->mutable_up(), PatientToWorld(volume.metadata().direction, {0, 0, 1}));
  sky->set_intensity(1);
  return scene;
}

bool AddDefaultLights(v1::Scene& scene, const Volume& volume) {
  if (scene.lights_size() > 0) return false;
  *scene.mutable_lights() = MakePresetScene(DefaultPreset(volume), volume).lights();
  return true;
}

}  // namespace cinevol

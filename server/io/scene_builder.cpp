// From the proto scene model to renderer inputs.
#include "io/scene_builder.h"

#include <cmath>

#include "encode/image_codecs.h"
#include "io/presets.h"

namespace cinevol {
namespace {

Vec3f ToVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3f ToColor(const v1::Color& c) { return {c.r(), c.g(), c.b()}; }

// A patient direction (LPS) in the volume's index space, which is world space
// for rendering: the transpose of the direction cosines maps LPS to index.
Vec3f PatientToWorld(const Volume& volume, Vec3f lps) {
  const auto& d = volume.metadata().direction;
  Vec3f w;
  for (int c = 0; c < 3; ++c) w[c] = float(d[0 * 3 + c] * lps.x + d[1 * 3 + c] * lps.y + d[2 * 3 + c] * lps.z);
  return Normalize(w);
}

// Where the eye sits (as a patient direction) and which way is up on screen.
// Lateral and frontal views keep the head up; axial views put anterior up and
// the patient's right on the viewer's left, as radiologists read them.
void NamedViewDirections(v1::NamedView view, Vec3f& eye_side, Vec3f& up) {
  const Vec3f kLeft{1, 0, 0}, kPosterior{0, 1, 0}, kSuperior{0, 0, 1};
  up = kSuperior;
  switch (view) {
    case v1::POSTERIOR: eye_side = kPosterior; break;
    case v1::LEFT: eye_side = kLeft; break;
    case v1::RIGHT: eye_side = -kLeft; break;
    case v1::SUPERIOR: eye_side = kSuperior; up = -kPosterior; break;
    case v1::INFERIOR: eye_side = -kSuperior; up = -kPosterior; break;
    default: eye_side = -kPosterior; break;  // ANTERIOR
  }
}

// The world-space box around the voxels the transfer function shows
// (opacity > 0), sampled on a grid of at most ~64^3 voxels; the whole volume
// when nothing shows.
void VisibleBounds(const Volume& volume, const TransferFunction& tf, Vec3f& lo, Vec3f& hi) {
  const Vec3i d = volume.dims();
  const Vec3f half = volume.extent_mm() * 0.5f;
  Vec3i step;
  for (int a = 0; a < 3; ++a) step[a] = std::max(1, d[a] / 64);
  Vec3i first = d, last{-1, -1, -1};
  for (int z = 0; z < d.z; z += step.z) {
    for (int y = 0; y < d.y; y += step.y) {
      for (int x = 0; x < d.x; x += step.x) {
        if (Evaluate(tf, volume.Value(x, y, z)).opacity <= 0.0f) continue;
        const Vec3i v{x, y, z};
        for (int a = 0; a < 3; ++a) {
          first[a] = std::min(first[a], v[a]);
          last[a] = std::max(last[a], v[a]);
        }
      }
    }
  }
  if (last.x < 0) {
    lo = -half;
    hi = half;
    return;
  }
  for (int a = 0; a < 3; ++a) {  // widen by one sampling step: the grid may miss the edges
    lo[a] = std::max(0, first[a] - step[a]) * volume.spacing_mm()[a] - half[a];
    hi[a] = std::min(d[a], last[a] + step[a] + 1) * volume.spacing_mm()[a] - half[a];
  }
}

}  // namespace

TransferFunction ResolveTransferFunction(const v1::TransferFunction& proto, const Volume& volume) {
  const v1::TransferFunction expanded =
      proto.points().empty() ? MakePreset(proto.preset(), volume.min_value(), volume.max_value()) : proto;
  TransferFunction tf;
  for (const auto& p : expanded.points()) {
    tf.points.push_back({p.value(), p.opacity(), ToColor(p.diffuse()), ToColor(p.specular()), p.roughness(),
                         ToColor(p.emission())});
  }
  // A preset supplies its own density and gradient factor unless the scene sets them.
  tf.density_scale = proto.points().empty() && !proto.has_density_scale() ? expanded.density_scale()
                                                                          : proto.density_scale();
  tf.gradient_factor = proto.points().empty() && !proto.has_gradient_factor() ? expanded.gradient_factor()
                                                                              : proto.gradient_factor();
  tf.phase_g = proto.phase_g();
  return tf;
}

Camera ResolveCamera(const v1::Camera& proto, const v1::RenderSettings& render, const Volume& volume,
                     const TransferFunction& tf) {
  const int width = static_cast<int>(render.width()), height = static_cast<int>(render.height());
  const float fov = proto.fov_y_deg();
  Vec3f eye, target, up{0, 0, 1};
  if (proto.view() != v1::NAMED_VIEW_UNSPECIFIED) {
    Vec3f side, up_lps;
    NamedViewDirections(proto.view(), side, up_lps);
    // Frame what the transfer function shows: back off until its bounding
    // sphere fits the narrower field of view.
    Vec3f lo, hi;
    VisibleBounds(volume, tf, lo, hi);
    target = (lo + hi) * 0.5f;
    const float radius = 0.5f * Length(hi - lo);
    const float half_fov_y = 0.5f * fov * kPi / 180.0f;
    const float half_fov = std::min(half_fov_y, std::atan(std::tan(half_fov_y) * width / height));
    eye = target + PatientToWorld(volume, side) * (1.02f * radius / std::sin(half_fov));
    up = PatientToWorld(volume, up_lps);
  } else {
    eye = ToVec(proto.eye());
    target = ToVec(proto.target());
    if (proto.has_up()) up = ToVec(proto.up());
    // A default up along the view falls back to another axis.
    if (Length(Cross(target - eye, up)) < 1e-6f * Length(target - eye)) up = {0, 1, 0};
  }
  Camera c = LookAt(eye, target, up, fov, width, height);
  c.lens_radius = proto.aperture_mm();
  if (proto.focal_distance_mm() > 0) c.focal_distance = proto.focal_distance_mm();
  return c;
}

LightSetup ResolveLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights) {
  LightSetup setup;
  for (const v1::Light& l : lights) {
    Light light;
    switch (l.kind_case()) {
      case v1::Light::kArea: {
        const auto& a = l.area();
        light.kind = LightKind::kArea;
        light.position = ToVec(a.center());
        light.edge_u = ToVec(a.edge_u());
        light.edge_v = ToVec(a.edge_v());
        const Vec3f n = Cross(light.edge_u, light.edge_v);
        light.area = Length(n);
        light.normal = n / light.area;
        light.emitted = ToColor(a.color()) * a.intensity();
        light.two_sided = a.two_sided();
        break;
      }
      case v1::Light::kPoint:
        light.kind = LightKind::kPoint;
        light.position = ToVec(l.point().position());
        light.emitted = ToColor(l.point().color()) * l.point().intensity();
        break;
      case v1::Light::kDirectional:
        light.kind = LightKind::kDirectional;
        light.direction = Normalize(ToVec(l.directional().direction()));
        light.emitted = ToColor(l.directional().color()) * l.directional().intensity();
        break;
      case v1::Light::kEnvironment: {
        const auto& e = l.environment();
        EnvironmentSetup& env = setup.environment;
        const float k = e.intensity();
        if (e.has_uniform()) {
          env.kind = Environment::Kind::kUniform;
          env.zenith = ToColor(e.uniform()) * k;
        } else if (e.has_gradient()) {
          env.kind = Environment::Kind::kGradient;
          env.zenith = ToColor(e.gradient().zenith()) * k;
          env.horizon = ToColor(e.gradient().horizon()) * k;
          env.ground = ToColor(e.gradient().ground()) * k;
          if (e.gradient().has_up()) env.up = Normalize(ToVec(e.gradient().up()));
        } else {
          env.kind = Environment::Kind::kMap;
          env.map = ReadExr(e.map());
          for (Vec3f& p : env.map.pixels) p *= k;
          env.rotation = e.rotation_deg() * kPi / 180.0f;
        }
        continue;  // not a Light
      }
      default:
        continue;
    }
    setup.lights.push_back(light);
  }
  return setup;
}

RenderSetup ResolveScene(const v1::Scene& scene, const Volume& volume) {
  RenderSetup setup;
  setup.transfer_function = ResolveTransferFunction(scene.transfer_function(), volume);
  setup.camera = ResolveCamera(scene.camera(), scene.render(), volume, setup.transfer_function);
  setup.lights = ResolveLights(scene.lights());
  setup.spp = static_cast<int>(scene.render().spp());
  setup.max_bounces = static_cast<int>(scene.render().max_bounces());
  setup.seed = scene.render().seed();
  setup.exposure = scene.camera().exposure();
  return setup;
}

}  // namespace cinevol

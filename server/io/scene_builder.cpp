// From the proto scene model to renderer inputs.
#include "io/scene_builder.h"

#include <cmath>

#include "encode/image_codecs.h"
#include "io/presets.h"

namespace cinevol {
namespace {

Vec3f ToVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3f ToColor(const v1::Color& c) { return {c.r(), c.g(), c.b()}; }

// The default camera fills this fraction of the viewport's shorter side.
constexpr float kFramingFill = 0.8f;

}  // namespace

Vec3f PatientToWorld(const Volume& volume, Vec3f lps) {
  // The transpose of the direction cosines maps LPS to index space, which is
  // world space for rendering.
  const auto& d = volume.metadata().direction;
  Vec3f w;
  for (int c = 0; c < 3; ++c) w[c] = float(d[0 * 3 + c] * lps.x + d[1 * 3 + c] * lps.y + d[2 * 3 + c] * lps.z);
  return Normalize(w);
}

ViewDirections NamedViewDirections(v1::NamedView view, const Volume& volume) {
  // Lateral and frontal views keep the head up; axial views put anterior up
  // and the patient's right on the viewer's left, as radiologists read them.
  const Vec3f kLeft{1, 0, 0}, kPosterior{0, 1, 0}, kSuperior{0, 0, 1};
  Vec3f to_eye = -kPosterior, up = kSuperior;
  switch (view) {
    case v1::POSTERIOR: to_eye = kPosterior; break;
    case v1::LEFT: to_eye = kLeft; break;
    case v1::RIGHT: to_eye = -kLeft; break;
    case v1::SUPERIOR: to_eye = kSuperior; up = -kPosterior; break;
    case v1::INFERIOR: to_eye = -kSuperior; up = -kPosterior; break;
    default: break;  // ANTERIOR
  }
  return {PatientToWorld(volume, to_eye), PatientToWorld(volume, up)};
}

Box VisibleBounds(const Volume& volume, const TransferFunction& tf) {
  const Vec3i blocks = volume.block_counts();
  const Vec3f half = volume.extent_mm() * 0.5f;
  Vec3i first = blocks, last{-1, -1, -1};
  std::size_t i = 0;
  for (int z = 0; z < blocks.z; ++z) {
    for (int y = 0; y < blocks.y; ++y) {
      for (int x = 0; x < blocks.x; ++x, ++i) {
        const Volume::ValueRange r = volume.block_ranges()[i];
        if (MaxOpacity(tf, r.lo, r.hi) <= 0.0f) continue;
        const Vec3i b{x, y, z};
        for (int a = 0; a < 3; ++a) {
          first[a] = std::min(first[a], b[a]);
          last[a] = std::max(last[a], b[a]);
        }
      }
    }
  }
  if (last.x < 0) return {-half, half};
  Box box;
  for (int a = 0; a < 3; ++a) {
    const float block_mm = Volume::kBlockSize * volume.spacing_mm()[a];
    box.lo[a] = first[a] * block_mm - half[a];
    box.hi[a] = std::min((last[a] + 1) * block_mm, 2 * half[a]) - half[a];
  }
  return box;
}

TransferFunction ResolveTransferFunction(const v1::TransferFunction& proto, const Volume& volume) {
  const std::string preset = proto.preset().empty() ? DefaultPreset(volume) : proto.preset();
  const v1::TransferFunction expanded =
      proto.points().empty() ? MakePreset(preset, AutoWindow(volume.histogram())) : proto;
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

float FramingDistance(const Box& box, const ViewDirections& view, float fov_y_deg, float aspect) {
  // Every corner of the box must project inside kFramingFill of the
  // viewport: |x| <= k_x (D - z) and |y| <= k_y (D - z), z towards the eye.
  const Vec3f right = Normalize(Cross(-view.to_eye, view.up));
  const Vec3f up = Cross(right, -view.to_eye);
  const float k_y = kFramingFill * std::tan(0.5f * fov_y_deg * kPi / 180.0f), k_x = k_y * aspect;
  const Vec3f centre = (box.lo + box.hi) * 0.5f;
  float distance = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3f p{corner & 1 ? box.hi.x : box.lo.x, corner & 2 ? box.hi.y : box.lo.y,
                  corner & 4 ? box.hi.z : box.lo.z};
    const Vec3f o = p - centre;
    const float fit = std::max(std::abs(Dot(o, right)) / k_x, std::abs(Dot(o, up)) / k_y);
    distance = std::max(distance, fit + Dot(o, view.to_eye));
  }
  return std::max(distance, 1e-3f + 0.5f * Length(box.hi - box.lo));  // never inside the box
}

Camera ResolveCamera(const v1::Camera& proto, const v1::RenderSettings& render, const Volume& volume,
                     const TransferFunction& tf) {
  const int width = static_cast<int>(render.width()), height = static_cast<int>(render.height());
  const float fov = proto.fov_y_deg();
  Vec3f eye, target, up{0, 0, 1};
  if (proto.view() != v1::NAMED_VIEW_UNSPECIFIED) {
    const ViewDirections view = NamedViewDirections(proto.view(), volume);
    const Box box = VisibleBounds(volume, tf);
    target = (box.lo + box.hi) * 0.5f;
    up = view.up;
    eye = target + view.to_eye * FramingDistance(box, view, fov, float(width) / float(height));
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
        light.visible = a.visible();
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
        env.visible = !e.has_visible() || e.visible();
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

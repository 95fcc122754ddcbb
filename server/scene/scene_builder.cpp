// From the proto scene model to renderer inputs.
#include "scene/scene_builder.h"

#include <algorithm>
#include <cmath>

#include "core/blocks.h"
#include "core/error.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "scene/scene_frame.h"

namespace cinevol {
namespace {

Vec3f ToVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }
Vec3f ToColor(const v1::Color& c) { return {c.r(), c.g(), c.b()}; }

// The default camera fills this fraction of the viewport's shorter side.
constexpr float kFramingFill = 0.8f;

}  // namespace

Vec3f PatientToWorld(const DirectionCosines& d, Vec3f lps) {
  VolumePlacement placement;
  placement.direction = d;
  return Normalize(placement.DirectionToVolume(lps));
}

ViewDirections NamedViewDirections(v1::NamedView view, const DirectionCosines& direction) {
  // Lateral and frontal views keep the head up; axial views put anterior up
  // and the patient's right on the viewer's left, as radiologists read them.
  const Vec3f kLeft{1, 0, 0}, kPosterior{0, 1, 0}, kSuperior{0, 0, 1};
  Vec3f to_eye = -kPosterior, up = kSuperior;
  switch (view) {
    case v1::POSTERIOR:
      to_eye = kPosterior;
      break;
    case v1::LEFT:
      to_eye = kLeft;
      break;
    case v1::RIGHT:
      to_eye = -kLeft;
      break;
    case v1::SUPERIOR:
      to_eye = kSuperior;
      up = -kPosterior;
      break;
    case v1::INFERIOR:
      to_eye = -kSuperior;
      up = -kPosterior;
      break;
    default:
      break;  // ANTERIOR
  }
  return {PatientToWorld(direction, to_eye), PatientToWorld(direction, up)};
}

namespace {

// True when one of the region's half-spaces has all of the box
// [lo, hi] on its cut side (enough to skip it; a box cut away by several
// planes together still counts as kept).
bool CutAway(const ClipRegion& clip, Vec3f lo, Vec3f hi) {
  for (int i = 0; i < clip.count; ++i) {
    const Vec4f h = clip.half_spaces[i];
    // The box corner farthest into the kept side.
    const Vec3f far{h.x > 0 ? hi.x : lo.x, h.y > 0 ? hi.y : lo.y, h.z > 0 ? hi.z : lo.z};
    if (Dot(Xyz(h), far) + h.w < 0.0f) return true;
  }
  return false;
}

}  // namespace

std::vector<bool> BlocksWithVisibleLabels(const Volume& volume, const LabelVolume& labels, const LabelSetup& setup) {
  const Vec3i blocks = volume.block_counts();
  // By stored value: labels, shells and the table (core/labels.h).
  std::vector<bool> visible(std::size_t(labels.value_count()));
  bool all_visible = true;
  for (std::size_t v = 0; v < visible.size(); ++v) {
    visible[v] = !setup.StyleOfValue(labels, int(v)).hidden();
    all_visible = all_visible && visible[v];
  }
  const std::size_t block_count = BlockTotal(blocks);
  if (all_visible) return std::vector<bool>(block_count, true);  // no need to read every voxel
  std::vector<std::uint8_t> shown(block_count, 0);               // bytes: blocks are written from several threads
  const Vec3i size{Volume::kBlockSize, Volume::kBlockSize, Volume::kBlockSize};
  ForEachBlock(volume.dims(), size, 0, [&](std::size_t i, Vec3i lo, Vec3i hi) {
    ForEachVoxel(labels.labels.data(), volume.dims(), lo, hi, [&](std::uint16_t v) { shown[i] |= visible[v]; });
  });
  return {shown.begin(), shown.end()};
}

std::vector<Vec3f> VisibleCorners(const Volume& volume, const TransferFunction& tf, const InView& in_view) {
  const ClipRegion& clip = in_view.clip;
  const Vec3i blocks = volume.block_counts(), n{blocks.x + 1, blocks.y + 1, blocks.z + 1};
  // Per corner of the block lattice, how many visible blocks touch it.
  std::vector<std::uint8_t> touching(std::size_t(n.x) * n.y * n.z, 0);
  auto at = [&](int x, int y, int z) { return (std::size_t(z) * n.y + y) * n.x + x; };
  // Haze that cannot take 20% of the light crossing a block is not framed.
  const Vec3f block_mm = volume.spacing_mm() * float(Volume::kBlockSize);
  const float min_opacity = 0.2f / std::max(1e-12f, tf.density_scale * MinComponent(block_mm));
  std::size_t i = 0;
  bool any = false;
  for (int z = 0; z < blocks.z; ++z) {
    for (int y = 0; y < blocks.y; ++y) {
      for (int x = 0; x < blocks.x; ++x, ++i) {
        const Volume::ValueRange r = volume.block_ranges()[i];
        if ((in_view.label_blocks && !(*in_view.label_blocks)[i]) || MaxOpacity(tf, r.lo, r.hi) <= min_opacity) {
          continue;
        }
        const Vec3f lo = ToFloat(Vec3i{x, y, z}) * block_mm - volume.extent_mm() * 0.5f;
        if (CutAway(clip, lo, lo + block_mm)) continue;
        any = true;
        for (int c = 0; c < 8; ++c) ++touching[at(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2))];
      }
    }
  }
  const Vec3f half = volume.extent_mm() * 0.5f;
  std::vector<Vec3f> points;
  for (int z = 0; z < n.z; ++z) {
    for (int y = 0; y < n.y; ++y) {
      for (int x = 0; x < n.x; ++x) {
        // Only the visible region's surface matters: a corner inside it (all
        // eight blocks visible) is never the farthest out.
        const int t = touching[at(x, y, z)];
        const bool outer = (x == 0 || x == blocks.x) && (y == 0 || y == blocks.y) && (z == 0 || z == blocks.z);
        if (any ? (t == 0 || t == 8) : !outer) continue;
        // The last block may be partial: clamp to the volume's box.
        const Vec3f p = ToFloat(Vec3i{x, y, z}) * block_mm - half;
        points.push_back(Min(p, half));
      }
    }
  }
  return points;
}

TransferFunction ResolveTransferFunction(const v1::TransferFunction& proto, const Volume& volume) {
  const v1::TransferFunction expanded = ExpandTransferFunction(proto, volume);
  TransferFunction tf;
  for (const auto& p : expanded.points()) {
    tf.points.push_back(
        {p.value(), p.opacity(), ToColor(p.diffuse()), ToColor(p.specular()), p.roughness(), ToColor(p.emission())});
  }
  tf.density_scale = expanded.density_scale();
  tf.gradient_factor = expanded.gradient_factor();
  tf.phase_g = expanded.phase_g();
  return tf;
}

Framing FrameView(const std::vector<Vec3f>& points, const ViewDirections& view, float fov_y_deg, float aspect) {
  const Vec3f forward = -view.to_eye;
  const Vec3f right = Normalize(Cross(forward, view.up)), up = Cross(right, forward);
  // A point at screen offsets (x, y) and depth z towards the eye fits when
  // |x| <= k_x (D - z) and |y| <= k_y (D - z).
  const float k_y = kFramingFill * std::tan(0.5f * fov_y_deg * kPi / 180.0f), k_x = k_y * aspect;
  Vec3f lo = points.front(), hi = points.front();
  for (const Vec3f& p : points) lo = Min(lo, p), hi = Max(hi, p);
  Framing f{(lo + hi) * 0.5f, 0};
  // Perspective makes near points look larger: fit, then centre what the
  // eye sees and fit again.
  for (int pass = 0; pass < 3; ++pass) {
    float nearest = 0;
    f.distance = 0;
    for (const Vec3f& p : points) {
      const Vec3f o = p - f.target;
      const float z = Dot(o, view.to_eye);
      f.distance = std::max(f.distance, std::max(std::abs(Dot(o, right)) / k_x, std::abs(Dot(o, up)) / k_y) + z);
      nearest = std::max(nearest, z);
    }
    f.distance = std::max(f.distance, nearest + 1e-3f * Length(hi - lo) + 1e-6f);  // every point in front
    if (pass == 2) break;
    float x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;  // tangents seen from the eye
    for (const Vec3f& p : points) {
      const Vec3f o = p - f.target;
      const float depth = f.distance - Dot(o, view.to_eye);
      x0 = std::min(x0, Dot(o, right) / depth), x1 = std::max(x1, Dot(o, right) / depth);
      y0 = std::min(y0, Dot(o, up) / depth), y1 = std::max(y1, Dot(o, up) / depth);
    }
    f.target += (right * (x0 + x1) + up * (y0 + y1)) * (0.5f * f.distance);
  }
  return f;
}

Camera ResolveCamera(const v1::Camera& proto, const v1::RenderSettings& render, const Volume& volume,
                     const TransferFunction& tf, const InView& in_view) {
  const int width = static_cast<int>(render.width()), height = static_cast<int>(render.height());
  const float fov = proto.fov_y_deg();
  Vec3f eye, target, up{0, 0, 1};
  if (proto.view() != v1::NAMED_VIEW_UNSPECIFIED && proto.has_eye() && proto.has_target()) {
    // A view button: the same target and distance, seen from the view's side.
    const ViewDirections view = NamedViewDirections(proto.view(), volume.metadata().direction);
    target = ToVec(proto.target());
    eye = target + view.to_eye * Length(ToVec(proto.eye()) - target);
    up = view.up;
  } else if (proto.view() != v1::NAMED_VIEW_UNSPECIFIED) {
    const ViewDirections view = NamedViewDirections(proto.view(), volume.metadata().direction);
    const Framing framing = FrameView(VisibleCorners(volume, tf, in_view), view, fov, float(width) / float(height));
    target = framing.target;
    up = view.up;
    eye = target + view.to_eye * framing.distance;
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

LightSetup ResolveLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights,
                         const EnvironmentMapReader& read_map) {
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
          if (!read_map) throw InputError("lights: an environment map needs a reader here, and none was given");
          env.map = read_map(e.map());
          // Texels become radiance under the scene's limit (kMaxRadiance): a
          // map's NaN, infinite or negative texels give none.
          for (Vec3f& p : env.map.pixels) {
            for (int c = 0; c < 3; ++c) {
              const float radiance = p[c] * k;
              p[c] = radiance >= 0.0f ? std::min(radiance, kMaxRadiance) : 0.0f;
            }
          }
          // Within one turn first: FLT_MAX degrees in radians overflows float.
          env.rotation = float(std::remainder(double(e.rotation_deg()), 360.0) * kPi / 180.0);
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

RenderSetup ResolveScene(const v1::Scene& scene, const Volume& volume, const LabelVolume* labels,
                         const EnvironmentMapReader& read_map) {
  RenderSetup setup;
  setup.transfer_function = ResolveTransferFunction(scene.transfer_function(), volume);
  setup.clip = ResolveClipping(scene.clipping(), volume);
  setup.labels = ResolveLabels(scene.labels(), volume);
  const std::vector<bool> label_blocks =
      labels ? BlocksWithVisibleLabels(volume, *labels, setup.labels) : std::vector<bool>();
  setup.camera = ResolveCamera(scene.camera(), scene.render(), volume, setup.transfer_function,
                               {setup.clip, labels ? &label_blocks : nullptr});
  setup.lights = ResolveLights(scene.lights(), read_map);
  setup.spp = static_cast<int>(scene.render().spp());
  setup.max_bounces = static_cast<int>(scene.render().max_bounces());
  setup.seed = scene.render().seed();
  setup.exposure = scene.camera().exposure();
  setup.reconstruction = ResolveReconstruction(scene.render().reconstruction());
  return setup;
}

FusionSetup ResolveFusion(const v1::Fusion& fusion, const Volume& volume, const Volume& fused) {
  FusionSetup setup;
  setup.value_factor = fusion.suv() ? float(fused.metadata().suv_factor) : 1.0f;
  const VolumePlacement from = VolumePlacement::Of(volume), to = VolumePlacement::Of(fused);
  auto map = [&](Vec3f p) { return to.PointToVolume(from.PointToPatient(p)); };
  const Vec3f origin = map({0, 0, 0});
  setup.to_volume = {map({1, 0, 0}) - origin, map({0, 1, 0}) - origin, map({0, 0, 1}) - origin, origin};
  const v1::TransferFunction& tf = fusion.transfer_function();
  if (tf.points_size() == 0 && tf.preset().empty()) return setup;  // slices only
  setup.transfer_function = ResolveTransferFunction(tf, fused);
  for (TransferPoint& point : setup.transfer_function.points) point.value /= setup.value_factor;
  return setup;
}

Reconstruction ResolveReconstruction(v1::Reconstruction reconstruction) {
  return reconstruction == v1::TRICUBIC ? Reconstruction::kTricubic : Reconstruction::kTrilinear;
}

LabelSetup ResolveLabels(const v1::Labels& labels, const Volume& volume) {
  LabelSetup setup;
  setup.show_unlisted = !labels.has_show_unlisted() || labels.show_unlisted();
  setup.remove_table = labels.remove_table();
  for (const v1::LabelStyle& proto : labels.styles()) {
    LabelStyle& style = setup.styles[int(proto.value())];
    style.visible = !proto.has_visible() || proto.visible();
    style.opacity_scale = proto.has_opacity_scale() ? proto.opacity_scale() : 1.0f;
    style.has_color = proto.has_color();
    style.color = ToColor(proto.color());
    if (proto.has_transfer_function()) {
      style.transfer = static_cast<int>(setup.transfer_functions.size());
      setup.transfer_functions.push_back(ResolveTransferFunction(proto.transfer_function(), volume));
    }
  }
  return setup;
}

namespace {

// Keeps Dot(normal, x - point) >= 0, in world mm.
Vec4f HalfSpace(Vec3f normal, Vec3f point) {
  const Vec3f n = Normalize(normal);
  return ToVec4(n, -Dot(n, point));
}

}  // namespace

ClipRegion ResolveClipping(const v1::Clipping& clipping, const Volume& volume) {
  const VolumePlacement frame = VolumePlacement::Of(volume);  // patient LPS to the volume-centred frame
  ClipRegion region;
  if (clipping.has_crop_box()) {
    const v1::CropBox& b = clipping.crop_box();
    const bool oriented = b.has_axis_x() && b.has_axis_y();
    const Vec3f x = Normalize(oriented ? ToVec(b.axis_x()) : Vec3f{1, 0, 0});
    const Vec3f z = Normalize(Cross(x, oriented ? ToVec(b.axis_y()) : Vec3f{0, 1, 0}));
    const Vec3f y = Cross(z, x);
    const Vec3f center = frame.PointToVolume(ToVec(b.center())), half = ToVec(b.size()) * 0.5f;
    const Vec3f axes[3] = {frame.DirectionToVolume(x), frame.DirectionToVolume(y), frame.DirectionToVolume(z)};
    for (int a = 0; a < 3; ++a) {
      region.half_spaces[region.count++] = HalfSpace(axes[a], center - axes[a] * half[a]);
      region.half_spaces[region.count++] = HalfSpace(-axes[a], center + axes[a] * half[a]);
    }
    if (b.cap()) region.capped = (1u << 6) - 1;
  }
  for (const v1::ClipPlane& plane : clipping.planes()) {
    if (region.count == kMaxClipHalfSpaces) break;  // validation allows 6 planes
    if (plane.cap()) region.capped |= 1u << region.count;
    region.half_spaces[region.count++] =
        HalfSpace(frame.DirectionToVolume(ToVec(plane.normal())), frame.PointToVolume(ToVec(plane.point())));
  }
  return region;
}

}  // namespace cinevol

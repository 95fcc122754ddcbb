// A scene as a presentation state and back, and LoadPresentation: the instance found, retrieved and read.
#include "runtime/presentation_store.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <numbers>

#include "core/error.h"
#include "core/transfer_function.h"
#include "pacs/measurement_requests.h"
#include "pacs/pacs_error.h"
#include "scene/scene_file.h"

namespace cinevol::service {
namespace {

using pacs::Vec3d;

// ---- Small vector algebra in double: the IOD's numbers are FD ----

Vec3d ToD(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }
v1::Vec3 ToVec(const Vec3d& v) {
  v1::Vec3 out;
  out.set_x(float(v[0]));
  out.set_y(float(v[1]));
  out.set_z(float(v[2]));
  return out;
}
Vec3d Add(const Vec3d& a, const Vec3d& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3d Sub(const Vec3d& a, const Vec3d& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3d Scale(const Vec3d& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double Dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3d Cross(const Vec3d& a, const Vec3d& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double Norm(const Vec3d& a) { return std::sqrt(Dot(a, a)); }
Vec3d Unit(const Vec3d& a) { return Scale(a, 1 / Norm(a)); }
bool Near(const Vec3d& a, const Vec3d& b, double tolerance) { return Norm(Sub(a, b)) <= tolerance; }

constexpr double kNearMm = 1;        // the near plane: closer than any camera cinevol places
constexpr double kSameMm = 1e-3;     // recipe and standard agree on a position within this
constexpr double kSameAngle = 1e-6;  // ... and on a unit vector
constexpr float kDefaultFovY = 30;
constexpr int kDefaultWidth = 640, kDefaultHeight = 480;

// ---- The view ----

pacs::RenderGeometry GeometryOf(const v1::Camera& camera, const v1::RenderSettings& render, double depth_mm) {
  pacs::RenderGeometry g;
  g.viewpoint = ToD(camera.eye());
  g.look_at = ToD(camera.target());
  g.up = camera.has_up() ? ToD(camera.up()) : Vec3d{0, 0, 1};
  const double fov = (camera.has_fov_y_deg() ? camera.fov_y_deg() : kDefaultFovY) * std::numbers::pi / 180;
  const double aspect = double(render.has_width() ? render.width() : kDefaultWidth) /
                        double(render.has_height() ? render.height() : kDefaultHeight);
  const double far = std::max(Norm(Sub(g.look_at, g.viewpoint)) + depth_mm, 2 * kNearMm);
  const double half_height = far * std::tan(fov / 2), half_width = half_height * aspect;
  g.field_of_view = {-half_width, half_width, half_height, -half_height, kNearMm, far};
  return g;
}

// The vertical field of view (degrees) and the aspect ratio a Render Field of View makes.
std::pair<double, double> FovAndAspect(const pacs::RenderGeometry& g) {
  const auto& f = g.field_of_view;
  const double height = f[2] - f[3], width = f[1] - f[0];
  return {2 * std::atan(height / 2 / f[5]) * 180 / std::numbers::pi, width / height};
}

// ---- Cropping ----

// A clip plane (a point, the normal towards what is kept) as Volume Cropping writes it.
pacs::CroppingPlane PlaneOf(const Vec3d& point, const Vec3d& kept_normal) {
  const Vec3d n = Unit(kept_normal);
  return {{-n[0], -n[1], -n[2], Dot(n, point)}};
}

v1::ClipPlane ClipPlaneOf(const pacs::CroppingPlane& p) {
  const Vec3d outward{p.plane[0], p.plane[1], p.plane[2]};
  v1::ClipPlane plane;
  *plane.mutable_point() = ToVec(Scale(outward, -p.plane[3]));
  *plane.mutable_normal() = ToVec(Scale(outward, -1));
  return plane;
}

bool SamePlane(const pacs::CroppingPlane& a, const pacs::CroppingPlane& b) {
  return Near({a.plane[0], a.plane[1], a.plane[2]}, {b.plane[0], b.plane[1], b.plane[2]}, kSameAngle * 10) &&
         std::abs(a.plane[3] - b.plane[3]) <= kSameMm;
}

// A crop box's axes as the renderer takes them (scene_builder.cpp): x, then z = x cross y, then y = z cross x.
std::array<Vec3d, 3> BoxAxes(const v1::CropBox& box) {
  const bool oriented = box.has_axis_x() && box.has_axis_y();
  const Vec3d x = Unit(oriented ? ToD(box.axis_x()) : Vec3d{1, 0, 0});
  const Vec3d z = Unit(Cross(x, oriented ? ToD(box.axis_y()) : Vec3d{0, 1, 0}));
  return {x, Cross(z, x), z};
}

std::vector<pacs::CroppingPlane> BoxPlanes(const v1::CropBox& box) {
  const auto axes = BoxAxes(box);
  const Vec3d center = ToD(box.center()), size = ToD(box.size());
  std::vector<pacs::CroppingPlane> planes;
  for (int a = 0; a < 3; ++a) {
    planes.push_back(PlaneOf(Sub(center, Scale(axes[a], size[a] / 2)), axes[a]));
    planes.push_back(PlaneOf(Add(center, Scale(axes[a], size[a] / 2)), Scale(axes[a], -1)));
  }
  return planes;
}

std::array<double, 6> BoxCorners(const v1::CropBox& box) {
  const auto axes = BoxAxes(box);
  const Vec3d size = ToD(box.size());
  Vec3d half{0, 0, 0};
  for (int a = 0; a < 3; ++a) half = Add(half, Scale(axes[a], size[a] / 2));
  const Vec3d lo = Sub(ToD(box.center()), half), hi = Add(ToD(box.center()), half);
  return {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
}

// Whether every axis of the box lies along one of the volume's index axes: a Bounding Box Crop can say it.
bool AlongVolumeAxes(const v1::CropBox& box, const std::array<double, 9>& direction) {
  for (const Vec3d& axis : BoxAxes(box)) {
    bool along = false;
    for (int c = 0; c < 3; ++c) {
      along |= std::abs(std::abs(Dot(axis, Unit({direction[c], direction[3 + c], direction[6 + c]}))) - 1) < kSameAngle;
    }
    if (!along) return false;
  }
  return true;
}

pacs::Cropping CroppingOf(const v1::Clipping& clipping, const std::array<double, 9>& direction) {
  pacs::Cropping c;
  if (clipping.has_crop_box()) {
    if (AlongVolumeAxes(clipping.crop_box(), direction)) {
      c.bounding_box = BoxCorners(clipping.crop_box());
    } else {
      c.plane_sets.push_back(BoxPlanes(clipping.crop_box()));
    }
  }
  if (clipping.planes_size() > 0) {
    std::vector<pacs::CroppingPlane>& planes = c.plane_sets.emplace_back();
    for (const v1::ClipPlane& p : clipping.planes()) planes.push_back(PlaneOf(ToD(p.point()), ToD(p.normal())));
  }
  return c;
}

// A bounding box as a crop box along `axes` (the series' row and column directions); the recipe's where it has
// the same corners (its cap).
v1::CropBox CropBoxOf(const std::array<double, 6>& corners, const std::array<double, 6>& axes, const v1::Scene& recipe) {
  const Vec3d lo{corners[0], corners[1], corners[2]}, hi{corners[3], corners[4], corners[5]};
  if (recipe.clipping().has_crop_box()) {
    const std::array<double, 6> theirs = BoxCorners(recipe.clipping().crop_box());
    if (Near(lo, {theirs[0], theirs[1], theirs[2]}, kSameMm) && Near(hi, {theirs[3], theirs[4], theirs[5]}, kSameMm)) {
      return recipe.clipping().crop_box();
    }
  }
  v1::CropBox box;
  const Vec3d x = Unit({axes[0], axes[1], axes[2]}), y = Unit({axes[3], axes[4], axes[5]}), z = Cross(x, y);
  const Vec3d diagonal = Sub(hi, lo);
  *box.mutable_center() = ToVec(Scale(Add(lo, hi), 0.5));
  *box.mutable_size() = ToVec({std::abs(Dot(diagonal, x)), std::abs(Dot(diagonal, y)), std::abs(Dot(diagonal, z))});
  if (!Near(x, {1, 0, 0}, kSameAngle) || !Near(y, {0, 1, 0}, kSameAngle)) {
    *box.mutable_axis_x() = ToVec(x);
    *box.mutable_axis_y() = ToVec(y);
  }
  return box;
}

bool SamePlanes(const std::vector<pacs::CroppingPlane>& a, const std::vector<pacs::CroppingPlane>& b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), SamePlane);
}

v1::Clipping ClippingOf(const pacs::Cropping& cropping, const std::array<double, 6>& axes, const v1::Scene& recipe) {
  v1::Clipping clipping;
  if (cropping.bounding_box) *clipping.mutable_crop_box() = CropBoxOf(*cropping.bounding_box, axes, recipe);
  for (const std::vector<pacs::CroppingPlane>& set : cropping.plane_sets) {
    // Six planes of the recipe's crop box (one not along the volume's axes) are that box.
    if (recipe.clipping().has_crop_box() && !clipping.has_crop_box() &&
        SamePlanes(set, BoxPlanes(recipe.clipping().crop_box()))) {
      *clipping.mutable_crop_box() = recipe.clipping().crop_box();
      continue;
    }
    for (const pacs::CroppingPlane& p : set) {
      if (clipping.planes_size() == int(pacs::kMaxPlanesInASet)) {
        throw InputError(fmt::format("the presentation state crops by more clip planes than a scene holds ({})",
                                     pacs::kMaxPlanesInASet));
      }
      v1::ClipPlane* plane = clipping.add_planes();
      *plane = ClipPlaneOf(p);
      for (const v1::ClipPlane& theirs : recipe.clipping().planes()) {  // the same plane: the recipe's, with its cap
        if (SamePlane(p, PlaneOf(ToD(theirs.point()), ToD(theirs.normal())))) *plane = theirs;
      }
    }
  }
  return clipping;
}

// ---- Colour and opacity ----

std::uint16_t Quantized(float unit) {
  return std::uint16_t(std::lround(65535.0 * std::clamp(double(unit), 0.0, 1.0)));
}

double DensityScale(const v1::TransferFunction& tf) { return tf.has_density_scale() ? tf.density_scale() : 1.0; }

// `tf` (points) sampled onto the palette over its points' values: [first, last] is the window. An entry's alpha is
// the opacity of one sampling step through its extinction (opacity times the density scale, per mm): 1 - e^(-sigma
// step), with the step that makes the densest entry's e^-1, so the 16 bits cover the extinctions the function has.
pacs::Classification ClassificationOf(const v1::TransferFunction& tf, std::optional<double> step = std::nullopt) {
  TransferFunction function;
  double densest = 0;
  for (const v1::TransferFunctionPoint& p : tf.points()) {
    TransferPoint& point = function.points.emplace_back();
    point.value = p.value();
    point.opacity = p.opacity();
    point.diffuse = {p.diffuse().r(), p.diffuse().g(), p.diffuse().b()};
    densest = std::max(densest, p.opacity() * DensityScale(tf));
  }
  pacs::Classification c;
  const double lo = function.points.front().value, hi = function.points.back().value;
  c.window_width = hi > lo ? hi - lo : 1;
  c.window_center = hi > lo ? (lo + hi) / 2 : lo;
  c.description = tf.preset().substr(0, 64);
  c.sampling_step_mm = step ? *step : densest > 0 ? std::clamp(1 / densest, 1e-3, 100.0) : 1;
  c.rgba.resize(pacs::kPaletteEntries);
  for (int i = 0; i < pacs::kPaletteEntries; ++i) {
    const double value = c.window_center - c.window_width / 2 + c.window_width * i / (pacs::kPaletteEntries - 1);
    const TransferPoint p = Evaluate(function, float(value));
    const double alpha = 1 - std::exp(-p.opacity * DensityScale(tf) * c.sampling_step_mm);
    c.rgba[i] = {Quantized(p.diffuse.x), Quantized(p.diffuse.y), Quantized(p.diffuse.z), Quantized(float(alpha))};
  }
  return c;
}

bool SamePalette(const pacs::Classification& a, const pacs::Classification& b) {
  if (a.rgba.size() != b.rgba.size() || std::abs(a.window_center - b.window_center) > 1e-3 ||
      std::abs(a.window_width - b.window_width) > 1e-3) {
    return false;
  }
  for (std::size_t i = 0; i < a.rgba.size(); ++i) {
    for (int k = 0; k < 4; ++k) {
      if (std::abs(int(a.rgba[i][k]) - int(b.rgba[i][k])) > 1) return false;
    }
  }
  return true;
}

// A palette as transfer-function points: at most 256 of its entries, evenly spaced, the last included; each alpha
// back to an extinction over the sampling step, the densest one's the density scale. The shading's specular
// intensity and shininess become every point's specular colour and roughness.
v1::TransferFunction PointsOf(const pacs::Classification& c, const pacs::Shading& shading) {
  v1::TransferFunction tf;
  const std::size_t n = c.rgba.size(), points = std::min<std::size_t>(n, 256);
  const auto extinction = [&](std::size_t i) {  // per mm; an opaque entry as the 16 bits' most
    return -std::log(1 - std::min(c.rgba[i][3], std::uint16_t(65534)) / 65535.0) / c.sampling_step_mm;
  };
  double densest = 0;
  for (std::size_t i = 0; i < n; ++i) densest = std::max(densest, extinction(i));
  tf.set_density_scale(float(densest > 0 ? densest : 1));
  for (std::size_t k = 0; k < points; ++k) {
    const std::size_t i = k * (n - 1) / (points - 1);
    v1::TransferFunctionPoint* p = tf.add_points();
    p->set_value(float(c.window_center - c.window_width / 2 + c.window_width * double(i) / double(n - 1)));
    p->set_opacity(float(densest > 0 ? extinction(i) / densest : 0));
    p->mutable_specular()->set_r(float(shading.specular));
    p->mutable_specular()->set_g(float(shading.specular));
    p->mutable_specular()->set_b(float(shading.specular));
    p->set_roughness(float(1 - shading.shininess));
    p->mutable_diffuse()->set_r(float(c.rgba[i][0] / 65535.0));
    p->mutable_diffuse()->set_g(float(c.rgba[i][1] / 65535.0));
    p->mutable_diffuse()->set_b(float(c.rgba[i][2] / 65535.0));
  }
  return tf;
}

// ---- Label styles through a SEG ----

// A label's palette: the image's transfer function in its colour, its extinction times its opacity scale, over the
// image's sampling step (one Sampling Step Size for every input).
pacs::Classification SegmentPalette(const v1::TransferFunction& tf, const v1::LabelStyle& style, double step) {
  v1::TransferFunction styled = tf;
  for (v1::TransferFunctionPoint& p : *styled.mutable_points()) {
    if (style.has_color()) *p.mutable_diffuse() = style.color();
  }
  styled.set_density_scale(float(DensityScale(tf) * (style.has_opacity_scale() ? style.opacity_scale() : 1.0)));
  return ClassificationOf(styled, step);
}

pacs::Segmentation SegmentationOf(const v1::Scene& scene, const SegSource& source, double step) {
  pacs::Segmentation seg;
  seg.sop_instance_uid = source.sop_instance_uid;
  seg.series_uid = source.series_uid;
  seg.show_unlisted = !scene.labels().has_show_unlisted() || scene.labels().show_unlisted();
  for (const v1::LabelStyle& style : scene.labels().styles()) {
    seg.styled.push_back(std::uint16_t(style.value()));
    if (style.has_visible() && !style.visible()) continue;
    seg.shown.push_back({std::uint16_t(style.value()), SegmentPalette(scene.transfer_function(), style, step)});
  }
  return seg;
}

// The entry where a palette is most opaque.
std::size_t Densest(const pacs::Classification& c) {
  std::size_t densest = 0;
  for (std::size_t i = 0; i < c.rgba.size(); ++i) densest = c.rgba[i][3] > c.rgba[densest][3] ? i : densest;
  return densest;
}

// Label styles as the standard says them: a shown segment's colour at its palette's most opaque entry, its opacity
// scale the ratio of its extinction there to the image's; a styled segment not shown, hidden.
v1::Labels LabelsOf(const pacs::Segmentation& seg, const pacs::Classification& image) {
  v1::Labels labels;
  if (!seg.show_unlisted) labels.set_show_unlisted(false);
  const auto extinction = [](const pacs::Classification& c, std::size_t i) {
    return -std::log(1 - std::min(c.rgba[i][3], std::uint16_t(65534)) / 65535.0) / c.sampling_step_mm;
  };
  for (const std::uint16_t value : seg.styled) {
    v1::LabelStyle& style = *labels.add_styles();
    style.set_value(value);
    const auto shown = std::find_if(seg.shown.begin(), seg.shown.end(),
                                    [&](const pacs::SegmentShown& s) { return s.number == value; });
    if (shown == seg.shown.end()) {
      style.set_visible(false);
      continue;
    }
    const std::size_t at = Densest(shown->palette);
    style.mutable_color()->set_r(float(shown->palette.rgba[at][0] / 65535.0));
    style.mutable_color()->set_g(float(shown->palette.rgba[at][1] / 65535.0));
    style.mutable_color()->set_b(float(shown->palette.rgba[at][2] / 65535.0));
    const bool comparable = seg.show_unlisted && image.rgba.size() == shown->palette.rgba.size();
    const double base = comparable ? extinction(image, at) : 0;
    if (base > 0) style.set_opacity_scale(float(extinction(shown->palette, at) / base));
  }
  return labels;
}

// The recipe's label styles where they say what the standard's do (the same labels shown and hidden, colours within
// a step of 255): they keep what the standard cannot (a label's own transfer function).
bool SameLabels(const v1::Labels& standard, const v1::Labels& recipe) {
  const auto shows_unlisted = [](const v1::Labels& l) { return !l.has_show_unlisted() || l.show_unlisted(); };
  if (standard.styles_size() != recipe.styles_size() || shows_unlisted(standard) != shows_unlisted(recipe)) return false;
  for (int i = 0; i < standard.styles_size(); ++i) {
    const v1::LabelStyle &a = standard.styles(i), &b = recipe.styles(i);
    const bool a_visible = !a.has_visible() || a.visible(), b_visible = !b.has_visible() || b.visible();
    if (a.value() != b.value() || a_visible != b_visible) return false;
    if (a_visible && b.has_color() &&
        (std::abs(a.color().r() - b.color().r()) > 2 / 255.0 || std::abs(a.color().g() - b.color().g()) > 2 / 255.0 ||
         std::abs(a.color().b() - b.color().b()) > 2 / 255.0)) {
      return false;
    }
  }
  return true;
}

// The direction light travels from the scene's first light that has one; else down the view.
Vec3d LightDirectionOf(const v1::Scene& scene);

// The Phong stand-in: the light's direction; the transfer function's mean specular colour and smoothness.
pacs::Shading ShadingOf(const v1::Scene& scene) {
  pacs::Shading shading;
  shading.light_direction = LightDirectionOf(scene);
  double specular = 0, roughness = 0;
  const auto& points = scene.transfer_function().points();
  for (const v1::TransferFunctionPoint& p : points) {
    specular += (p.specular().r() + p.specular().g() + p.specular().b()) / 3;
    roughness += p.roughness();
  }
  if (!points.empty()) {
    shading.specular = std::clamp(specular / points.size(), 0.0, 1.0);
    shading.shininess = std::clamp(1 - roughness / points.size(), 0.0, 1.0);
  }
  return shading;
}

Vec3d LightDirectionOf(const v1::Scene& scene) {
  const Vec3d target = ToD(scene.camera().target());
  for (const v1::Light& light : scene.lights()) {
    Vec3d d{0, 0, 0};
    if (light.has_directional()) d = ToD(light.directional().direction());
    if (light.has_point()) d = Sub(target, ToD(light.point().position()));
    if (light.has_area()) d = Sub(target, ToD(light.area().center()));
    if (Norm(d) > 0) return Unit(d);
  }
  const Vec3d view = Sub(target, ToD(scene.camera().eye()));
  return Norm(view) > 0 ? Unit(view) : Vec3d{0, 0, -1};
}

}  // namespace

pacs::PresentationState PresentationOf(const v1::Scene& scene, const Volume& volume, const std::optional<SegSource>& seg) {
  pacs::PresentationState state;
  const Vec3f extent = volume.extent_mm();
  state.geometry = GeometryOf(scene.camera(), scene.render(), Norm({extent.x, extent.y, extent.z}));
  state.cropping = CroppingOf(scene.clipping(), volume.metadata().direction);
  state.classification = ClassificationOf(scene.transfer_function());
  if (seg && StylesLabels(scene.labels()) && scene.labels().styles_size() > 0) {
    state.segmentation = SegmentationOf(scene, *seg, state.classification.sampling_step_mm);
  }
  state.shading = ShadingOf(scene);
  state.description = scene.transfer_function().preset().empty()
                          ? std::string("cinevol render")
                          : fmt::format("cinevol render: {}", scene.transfer_function().preset()).substr(0, 64);
  google::protobuf::util::JsonPrintOptions options;
  if (!google::protobuf::util::MessageToJsonString(scene, &state.recipe_json, options).ok()) {
    throw std::runtime_error("the scene could not be written as JSON for the presentation state");
  }
  return state;
}

v1::Scene SceneOf(const pacs::ReadPresentation& read, const std::array<double, 6>& volume_axes) {
  const pacs::PresentationState& state = read.state;
  v1::Scene recipe;
  if (!state.recipe_json.empty() &&
      !google::protobuf::util::JsonStringToMessage(state.recipe_json, &recipe).ok()) {
    throw InputError("the presentation state's cinevol recipe is not a scene");
  }
  if (!state.geometry.perspective) {
    throw InputError("the presentation state asks for an ORTHOGRAPHIC view, which cinevol's camera cannot show");
  }
  // What the standard says not, the recipe's; then the standard's over it.
  v1::Scene scene = recipe;
  scene.clear_volume();
  scene.set_frame(v1::PATIENT_LPS);
  const pacs::RenderGeometry& g = state.geometry;
  const auto [fov_y, aspect] = FovAndAspect(g);
  v1::Camera& camera = *scene.mutable_camera();
  camera.set_view(v1::NAMED_VIEW_UNSPECIFIED);
  *camera.mutable_eye() = ToVec(g.viewpoint);
  *camera.mutable_target() = ToVec(g.look_at);
  *camera.mutable_up() = ToVec(g.up);
  camera.set_fov_y_deg(float(fov_y));
  v1::RenderSettings& render = *scene.mutable_render();
  const double recipe_aspect = double(render.has_width() ? render.width() : kDefaultWidth) /
                               double(render.has_height() ? render.height() : kDefaultHeight);
  if (!recipe.has_render() || std::abs(recipe_aspect - aspect) > 1e-3 * aspect) {
    render.set_height(std::uint32_t(kDefaultHeight));
    render.set_width(std::uint32_t(std::clamp(std::lround(kDefaultHeight * aspect), 1l, 8192l)));
  }
  *scene.mutable_clipping() = ClippingOf(state.cropping, volume_axes, recipe);
  const bool recipe_palette = recipe.transfer_function().points_size() > 0 &&
                              SamePalette(ClassificationOf(recipe.transfer_function()), state.classification);
  if (!recipe_palette) {
    v1::TransferFunction tf = PointsOf(state.classification, state.shading);
    if (recipe.transfer_function().has_gradient_factor()) {
      tf.set_gradient_factor(recipe.transfer_function().gradient_factor());
    }
    tf.set_preset(state.classification.description);
    *scene.mutable_transfer_function() = std::move(tf);
  }
  if (state.segmentation) {
    const v1::Labels labels = LabelsOf(*state.segmentation, state.classification);
    *scene.mutable_labels() = SameLabels(labels, recipe.labels()) ? recipe.labels() : labels;
  }
  return scene;
}

v1::LoadPresentationResponse LoadPresentation(const pacs::DicomWebClient& pacs,
                                              const v1::LoadPresentationRequest& request,
                                              const std::atomic<bool>* cancel) {
  std::string study = request.study_uid(), series = request.series_uid(), instance = request.sop_instance_uid();
  if (study.empty() != series.empty()) {
    throw InputError("study_uid and series_uid: give both, or neither and the instance's UID alone");
  }
  if (study.empty()) {
    if (instance.empty()) throw InputError("sop_instance_uid: name the presentation state");
    const pacs::InstanceLocation place = pacs::FindInstance(pacs, instance, cancel);
    study = place.study_uid;
    series = place.series_uid;
  }
  pacs::CheckUid(study, "study_uid");
  pacs::CheckUid(series, "series_uid");
  if (instance.empty()) {
    const std::vector<pacs::InstanceSummary> listed = pacs.ListInstances(study, series, cancel);
    if (listed.size() != 1) {
      throw InputError(fmt::format("sop_instance_uid: series {} holds {} instances; name the presentation state",
                                   series, listed.size()));
    }
    instance = listed.front().sop_instance_uid;
  }
  const pacs::ReadPresentation read = pacs::ReadPresentationState(
      pacs::RetrieveInstance(pacs, study, series, instance, pacs::kMaxPresentationBytes, cancel));
  if (read.uids.sop_instance_uid != instance) {
    throw pacs::PacsError(fmt::format("PACS '{}' answered a retrieve of presentation state {} with another instance",
                                      pacs.config().name, instance));
  }
  // The series it presents, there: a state naming one the PACS lacks is refused by name, not by the first request
  // that misses it.
  bool held = false;
  try {
    held = !pacs.ListInstances(read.source_study_uid, read.source_series_uid, cancel).empty();
  } catch (const pacs::PacsError& e) {
    if (e.http_status() != 404) throw;
  }
  if (!held) {
    throw pacs::PacsError(
        fmt::format("presentation state {} presents series {} of study {}, which PACS '{}' does not hold", instance,
                    read.source_series_uid, read.source_study_uid, pacs.config().name),
        404);
  }
  // The axes of a bounding box: the input series' (its first image's rows and columns).
  std::array<double, 6> axes{1, 0, 0, 0, 1, 0};
  if (read.state.cropping.bounding_box) {
    axes = pacs::FetchImagePlane(pacs, read.source_study_uid, read.source_series_uid, read.input_images.front(), cancel)
               .orientation;
  }
  v1::LoadPresentationResponse response;
  *response.mutable_scene() = SceneOf(read, axes);
  response.set_study_uid(read.source_study_uid);
  response.set_series_uid(read.source_series_uid);
  response.set_label(read.state.label);
  response.set_description(read.state.description);
  if (read.state.segmentation) response.set_labels_series_uid(read.state.segmentation->series_uid);
  if (!read.state.rendered_sop_instance_uid.empty()) {
    v1::StoredObject& rendered = *response.mutable_rendered();
    rendered.set_pacs(pacs.config().name);
    rendered.set_study_uid(read.uids.study_uid);
    rendered.set_series_uid(read.state.rendered_series_uid);
    rendered.set_sop_instance_uid(read.state.rendered_sop_instance_uid);
  }
  return response;
}

}  // namespace cinevol::service

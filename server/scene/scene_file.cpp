// Scene JSON through protobuf's own JSON mapping, plus defaults and validation.
#include "scene/scene_file.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/labels.h"
#include "scene/phantom_spec.h"
#include "scene/presets.h"
#include "scene/scene_fields.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

// Collects problems; each names its field by its JSON path.
class Problems {
 public:
  void Add(const std::string& field, const std::string& what) { list_.push_back(fmt::format("{}: {}", field, what)); }
  void Finite(const std::string& field, float v) {
    if (!std::isfinite(v)) Add(field, fmt::format("{} is not a finite number", v));
  }
  void InRange(const std::string& field, float v, float lo, float hi) {
    if (!std::isfinite(v) || v < lo || v > hi) Add(field, fmt::format("{:g} is outside [{:g}, {:g}]", v, lo, hi));
  }
  // The fields of `message` in `fields` (scene_fields.h), named `prefix` + name.
  template <class Message>
  void Numbers(const Message& message, std::span<const NumberField<Message>> fields, const std::string& prefix) {
    CheckRanges(message, fields, prefix, list_);
  }
  void Vec(const std::string& field, const v1::Vec3& v) {
    InRange(field + ".x", v.x(), -kMaxSceneMm, kMaxSceneMm);
    InRange(field + ".y", v.y(), -kMaxSceneMm, kMaxSceneMm);
    InRange(field + ".z", v.z(), -kMaxSceneMm, kMaxSceneMm);
  }
  // A vector that gives a direction: also long enough to normalise.
  void Direction(const std::string& field, const v1::Vec3& v);
  // A light's `field`.color and `field`.intensity: what they emit together
  // stays within kMaxRadiance.
  void Emitted(const std::string& field, const v1::Color& color, float intensity) {
    Color(field + ".color", color);
    if (std::isfinite(intensity) && intensity >= 0 && intensity <= kMaxRadiance) {
      Brightness(field + ".intensity", color, intensity);
    } else {
      InRange(field + ".intensity", intensity, 0, kMaxRadiance);
    }
  }
  // Colour x intensity at most kMaxRadiance in every channel; `field` is named.
  void Brightness(const std::string& field, const v1::Color& color, float intensity) {
    const double brightest = std::max({color.r(), color.g(), color.b()}) * double(intensity);
    if (std::isfinite(brightest) && brightest > kMaxRadiance) {
      Add(field, fmt::format("colour x intensity is {:g}, over the limit of {:g}", brightest, kMaxRadiance));
    }
  }
  void Color(const std::string& field, const v1::Color& c, float hi = INFINITY) {
    InRange(field + ".r", c.r(), 0, hi);
    InRange(field + ".g", c.g(), 0, hi);
    InRange(field + ".b", c.b(), 0, hi);
  }
  std::vector<std::string> Take() { return std::move(list_); }

 private:
  std::vector<std::string> list_;
};

double Norm(const v1::Vec3& v) {
  return std::sqrt(double(v.x()) * v.x() + double(v.y()) * v.y() + double(v.z()) * v.z());
}

void Problems::Direction(const std::string& field, const v1::Vec3& v) {
  Vec(field, v);
  if (!(Norm(v) >= kMinDirectionLength)) {
    Add(field, fmt::format("is shorter than {:g}: no direction", kMinDirectionLength));
  }
}

// Area lights smaller than this (mm^2) have no normal float can hold.
constexpr double kMinArea = 1e-6;

// |a x b| in double: float squares of what validation allows overflow or vanish.
double CrossNorm(const v1::Vec3& a, const v1::Vec3& b) {
  const double x = double(a.y()) * b.z() - double(a.z()) * b.y();
  const double y = double(a.z()) * b.x() - double(a.x()) * b.z();
  const double z = double(a.x()) * b.y() - double(a.y()) * b.x();
  return std::sqrt(x * x + y * y + z * z);
}

v1::Vec3 Sub(const v1::Vec3& a, const v1::Vec3& b) {
  v1::Vec3 d;
  d.set_x(a.x() - b.x());
  d.set_y(a.y() - b.y());
  d.set_z(a.z() - b.z());
  return d;
}

void ValidateVolume(const v1::VolumeSource& v, Problems& p) {
  switch (v.source_case()) {
    case v1::VolumeSource::kFile:
      if (v.file().empty()) p.Add("volume.file", "is empty");
      break;
    case v1::VolumeSource::kDicomFolder:
      if (v.dicom_folder().empty()) p.Add("volume.dicomFolder", "is empty");
      break;
    case v1::VolumeSource::kPhantom:
      try {
        ValidatePhantom(v.phantom());
      } catch (const InputError& e) {
        p.Add("volume.phantom", e.what());
      }
      break;
    default:
      // A scene for a volume named elsewhere (a session's volume_id, `--volume ID`): a presentation state's, or a
      // PACS series'. What loads a scene's own volume says when it has none (volume_loader.cpp).
      if (!v.labels().empty() || !v.series_uid().empty())
        p.Add("volume", "no source given (file, dicomFolder or phantom)");
  }
  if (!v.labels().empty() && v.has_phantom()) p.Add("volume.labels", "phantoms have no segmentation");
  if (!v.label_table().empty() && v.labels().empty()) p.Add("volume.labelTable", "names labels: set volume.labels too");
}

// `f`: the field's name in messages.
void ValidateTransferFunction(const v1::TransferFunction& tf, const std::string& f, Problems& p) {
  if (tf.points().empty() && !tf.preset().empty() && !IsPreset(tf.preset())) {
    p.Add(f + ".preset", fmt::format("unknown preset '{}'", tf.preset()));
  }
  for (int i = 0; i < tf.points_size(); ++i) {
    const auto& pt = tf.points(i);
    const std::string at = fmt::format("{}.points[{}]", f, i);
    p.Finite(at + ".value", pt.value());
    if (i > 0 && !(pt.value() > tf.points(i - 1).value())) {
      p.Add(at + ".value", fmt::format("{} is not greater than the previous point's {}; points must be "
                                       "sorted by strictly increasing value",
                                       pt.value(), tf.points(i - 1).value()));
    }
    p.InRange(at + ".opacity", pt.opacity(), 0, 1);
    p.Color(at + ".diffuse", pt.diffuse(), 1);
    p.Color(at + ".specular", pt.specular(), 1);
    p.InRange(at + ".roughness", pt.roughness(), 0, 1);
    p.Color(at + ".emission", pt.emission(), kMaxRadiance);
  }
  p.Numbers(tf, TransferFunctionNumbers(), f + ".");
}

void ValidateLabels(const v1::Labels& labels, Problems& p) {
  if (labels.styles_size() > 1024) p.Add("labels.styles", fmt::format("{} styles; at most 1024", labels.styles_size()));
  std::set<std::uint32_t> seen;
  int own = 0;
  for (int i = 0; i < labels.styles_size(); ++i) {
    const v1::LabelStyle& style = labels.styles(i);
    const std::string at = fmt::format("labels.styles[{}]", i);
    if (style.value() > 65535) p.Add(at + ".value", fmt::format("{} is outside [0, 65535]", style.value()));
    if (!seen.insert(style.value()).second)
      p.Add(at + ".value", fmt::format("label {} is styled twice", style.value()));
    if (style.has_color()) p.Color(at + ".color", style.color(), 1);
    if (style.has_opacity_scale()) p.InRange(at + ".opacityScale", style.opacity_scale(), 0, 1000);
    if (style.has_transfer_function()) {
      ValidateTransferFunction(style.transfer_function(), at + ".transferFunction", p);
      ++own;
    }
  }
  if (own > kMaxLabelTransferFunctions) {
    p.Add("labels.styles",
          fmt::format("{} labels with their own transfer function; at most {}", own, kMaxLabelTransferFunctions));
  }
}

void ValidateFusion(const v1::Fusion& fusion, Problems& p) {
  if (fusion.has_transfer_function())
    ValidateTransferFunction(fusion.transfer_function(), "fusion.transferFunction", p);
  const v1::FusionOverlay& o = fusion.overlay();
  if (!v1::ColorMap_IsValid(o.color_map())) {
    p.Add("fusion.overlay.colorMap", fmt::format("unknown colour map {}", int(o.color_map())));
  }
  if (o.has_window() != o.has_level()) p.Add("fusion.overlay", "set window and level together, or neither");
  if (o.has_window() && !(o.window() > 0 && o.window() <= 1e30f)) {
    p.Add("fusion.overlay.window", fmt::format("{} is not in (0, 1e30]", o.window()));
  }
  if (o.has_level()) p.InRange("fusion.overlay.level", o.level(), -1e30, 1e30);
  if (o.has_opacity()) p.InRange("fusion.overlay.opacity", o.opacity(), 0, 1);
}

void ValidateCamera(const v1::Camera& c, Problems& p) {
  if (!v1::NamedView_IsValid(c.view())) p.Add("camera.view", fmt::format("unknown named view {}", int(c.view())));
  const bool named = c.view() != v1::NAMED_VIEW_UNSPECIFIED;
  // A named view uses eye and target only when both are set (turned about the target).
  if (named ? c.has_eye() && c.has_target() : c.has_eye()) {
    p.Vec("camera.eye", c.eye());
    p.Vec("camera.target", c.target());
    const v1::Vec3 forward = Sub(c.target(), c.eye());
    if (Norm(forward) == 0.0) p.Add("camera.target", "equals camera.eye; the camera has no direction");
    if (!named && c.has_up()) {
      p.Direction("camera.up", c.up());
      if (Norm(c.up()) >= kMinDirectionLength && Norm(forward) > 0.0 &&
          CrossNorm(forward, c.up()) <= 1e-6 * Norm(forward) * Norm(c.up())) {
        p.Add("camera.up", "is parallel to the viewing direction (target - eye)");
      }
    }
  }
  p.Numbers(c, CameraNumbers(), "camera.");
}

// Positions within this of the volume (mm) are all any scan needs.
constexpr float kMaxClipMm = 1e6f;

void ValidateClipping(const v1::Clipping& c, Problems& p) {
  if (c.has_crop_box()) {
    const v1::CropBox& b = c.crop_box();
    p.Vec("clipping.cropBox.center", b.center());
    p.InRange("clipping.cropBox.size.x", b.size().x(), 1e-3f, kMaxClipMm);
    p.InRange("clipping.cropBox.size.y", b.size().y(), 1e-3f, kMaxClipMm);
    p.InRange("clipping.cropBox.size.z", b.size().z(), 1e-3f, kMaxClipMm);
    if (b.has_axis_x() || b.has_axis_y()) {
      p.Vec("clipping.cropBox.axisX", b.axis_x());
      p.Vec("clipping.cropBox.axisY", b.axis_y());
      if (!(Norm(b.axis_x()) >= 1e-6 && Norm(b.axis_y()) >= 1e-6 &&
            CrossNorm(b.axis_x(), b.axis_y()) > 1e-3 * Norm(b.axis_x()) * Norm(b.axis_y()))) {
        p.Add("clipping.cropBox", "axisX and axisY must both be set, of length at least 1e-6 and not parallel");
      }
    }
  }
  if (c.planes_size() > 6) p.Add("clipping.planes", fmt::format("{} planes; at most 6", c.planes_size()));
  for (int i = 0; i < c.planes_size(); ++i) {
    const std::string at = fmt::format("clipping.planes[{}]", i);
    p.Vec(at + ".point", c.planes(i).point());
    p.Vec(at + ".normal", c.planes(i).normal());
    if (!(Norm(c.planes(i).normal()) >= 1e-6)) p.Add(at + ".normal", "is shorter than 1e-6: no direction");
  }
}

void ValidateLight(const v1::Light& l, const std::string& at, bool& seen_environment, Problems& p) {
  switch (l.kind_case()) {
    case v1::Light::kArea: {
      const auto& a = l.area();
      p.Vec(at + ".area.center", a.center());
      p.Vec(at + ".area.edgeU", a.edge_u());
      p.Vec(at + ".area.edgeV", a.edge_v());
      if (!(CrossNorm(a.edge_u(), a.edge_v()) >= kMinArea)) {
        p.Add(at + ".area", fmt::format("zero area: |edgeU x edgeV| is {:g} mm^2, under {:g}",
                                        CrossNorm(a.edge_u(), a.edge_v()), kMinArea));
      }
      p.Emitted(at + ".area", a.color(), a.intensity());
      break;
    }
    case v1::Light::kPoint:
      p.Vec(at + ".point.position", l.point().position());
      p.Emitted(at + ".point", l.point().color(), l.point().intensity());
      break;
    case v1::Light::kDirectional:
      p.Direction(at + ".directional.direction", l.directional().direction());
      p.Emitted(at + ".directional", l.directional().color(), l.directional().intensity());
      break;
    case v1::Light::kEnvironment: {
      const auto& e = l.environment();
      if (seen_environment) p.Add(at + ".environment", "a second environment light; at most one is allowed");
      seen_environment = true;
      p.InRange(at + ".environment.intensity", e.intensity(), 0, kMaxRadiance);
      p.Finite(at + ".environment.rotationDeg", e.rotation_deg());
      // The sky's colours under the same limit as lights'.
      auto sky = [&](const std::string& field, const v1::Color& c) {
        p.Color(field, c);
        p.Brightness(field, c, e.intensity());
      };
      if (e.has_uniform()) sky(at + ".environment.uniform", e.uniform());
      if (e.has_gradient()) {
        sky(at + ".environment.gradient.zenith", e.gradient().zenith());
        sky(at + ".environment.gradient.horizon", e.gradient().horizon());
        sky(at + ".environment.gradient.ground", e.gradient().ground());
        if (e.gradient().has_up()) p.Direction(at + ".environment.gradient.up", e.gradient().up());
      }
      if (e.radiance_case() == v1::EnvironmentLight::kMap && e.map().empty()) {
        p.Add(at + ".environment.map", "is empty");
      }
      if (e.radiance_case() == v1::EnvironmentLight::RADIANCE_NOT_SET) {
        p.Add(at + ".environment", "no radiance given (uniform, gradient or map)");
      }
      break;
    }
    default:
      p.Add(at, "no light kind given (area, point, directional or environment)");
  }
}

void ValidateRender(const v1::RenderSettings& r, Problems& p) {
  p.Numbers(r, RenderNumbers(), "render.");
  if (!v1::Reconstruction_IsValid(r.reconstruction())) {
    p.Add("render.reconstruction", fmt::format("unknown value {}", int(r.reconstruction())));
  }
}

void ResolvePaths(v1::Scene& scene, const fs::path& base_dir) {
  if (base_dir.empty()) return;
  auto resolve = [&](std::string* path) {
    if (!path->empty() && fs::path(*path).is_relative()) *path = (base_dir / *path).lexically_normal().string();
  };
  auto* volume = scene.mutable_volume();
  if (volume->has_file()) resolve(volume->mutable_file());
  if (volume->has_dicom_folder()) resolve(volume->mutable_dicom_folder());
  resolve(volume->mutable_labels());
  resolve(volume->mutable_label_table());
  for (auto& light : *scene.mutable_lights()) {
    if (light.has_environment() && light.environment().has_map()) {
      resolve(light.mutable_environment()->mutable_map());
    }
  }
}

}  // namespace

void ApplyDefaults(v1::Scene& scene, unsigned parts) {
  if (parts & kTransferFunctionChanged) {
    v1::TransferFunction& tf = *scene.mutable_transfer_function();
    if (tf.points().empty()) {
      FillDefaults(tf, TransferFunctionNumbers(), {"densityScale", "gradientFactor"});  // a preset brings its own
    } else {
      FillDefaults(tf, TransferFunctionNumbers());
    }
  }
  if (parts & kCameraChanged) {
    v1::Camera& camera = *scene.mutable_camera();
    FillDefaults(camera, CameraNumbers());
    if (camera.view() == v1::NAMED_VIEW_UNSPECIFIED && !camera.has_eye()) camera.set_view(v1::ANTERIOR);
  }
  if (parts & (kCameraChanged | kSamplingChanged)) FillDefaults(*scene.mutable_render(), RenderNumbers());
  if ((parts & kFusionChanged) && scene.has_fusion()) {
    v1::Fusion& fusion = *scene.mutable_fusion();
    if (fusion.transfer_function().points_size() > 0)
      FillDefaults(*fusion.mutable_transfer_function(), TransferFunctionNumbers());
    if (fusion.overlay().color_map() == v1::COLOR_MAP_UNSPECIFIED) fusion.mutable_overlay()->set_color_map(v1::HOT);
    if (!fusion.overlay().has_opacity()) fusion.mutable_overlay()->set_opacity(0.5f);
  }
}

namespace {

// Measurements ride with whole scenes (files, CreateSession) and with their own event.
void ValidateMeasurements(const google::protobuf::RepeatedPtrField<v1::Measurement>& measurements, Problems& p) {
  if (measurements.size() > kMaxMeasurements) {
    p.Add("measurements", fmt::format("{} measurements; at most {}", measurements.size(), kMaxMeasurements));
    return;
  }
  for (int i = 0; i < measurements.size(); ++i) {
    const v1::Measurement& m = measurements[i];
    const std::string field = fmt::format("measurements[{}]", i);
    if (m.name().size() > kMaxMeasurementName) {
      p.Add(field + ".name", fmt::format("{} characters; at most {}", m.name().size(), kMaxMeasurementName));
    }
    if (m.points_size() != 2 && m.points_size() != 3) {
      p.Add(field + ".points", fmt::format("{} points; a distance has 2, an angle 3", m.points_size()));
    }
    for (int k = 0; k < std::min(m.points_size(), 3); ++k) {
      const v1::Vec3& v = m.points(k);
      for (const auto& [axis, value] : {std::pair{"x", v.x()}, {"y", v.y()}, {"z", v.z()}}) {
        p.InRange(fmt::format("{}.points[{}].{}", field, k, axis), value, -1e6f, 1e6f);
      }
    }
  }
}

void ValidateParts(const v1::Scene& scene, unsigned parts, Problems& p) {
  if (parts == kEverythingChanged) ValidateMeasurements(scene.measurements(), p);
  if ((parts & (kCameraChanged | kLightsChanged)) && !v1::SceneFrame_IsValid(scene.frame())) {
    p.Add("frame", fmt::format("unknown frame {}", int(scene.frame())));
  }
  if (parts & kTransferFunctionChanged) ValidateTransferFunction(scene.transfer_function(), "transferFunction", p);
  if (parts & kCameraChanged) ValidateCamera(scene.camera(), p);
  if (parts & kLightsChanged) {
    bool seen_environment = false;
    for (int i = 0; i < scene.lights_size(); ++i) {
      ValidateLight(scene.lights(i), fmt::format("lights[{}]", i), seen_environment, p);
    }
  }
  if (parts & (kCameraChanged | kSamplingChanged)) ValidateRender(scene.render(), p);
  if (parts & kClippingChanged) ValidateClipping(scene.clipping(), p);
  if (parts & kLabelsChanged) ValidateLabels(scene.labels(), p);
  if (parts & kFusionChanged) ValidateFusion(scene.fusion(), p);
}

}  // namespace

std::vector<std::string> ValidateScene(const v1::Scene& scene) {
  Problems p;
  ValidateVolume(scene.volume(), p);
  ValidateParts(scene, kEverythingChanged, p);
  return p.Take();
}

bool StylesLabels(const v1::Labels& labels) { return labels.styles_size() > 0 || labels.has_show_unlisted(); }

std::vector<std::string> ValidateMeasurements(const google::protobuf::RepeatedPtrField<v1::Measurement>& measurements) {
  Problems p;
  ValidateMeasurements(measurements, p);
  return p.Take();
}

std::vector<std::string> ValidateSceneParts(const v1::Scene& scene, unsigned parts) {
  Problems p;
  ValidateParts(scene, parts, p);
  return p.Take();
}

void CheckScene(const v1::Scene& scene) {
  const std::vector<std::string> problems = ValidateScene(scene);
  if (!problems.empty()) {
    throw InputError(fmt::format("invalid scene:\n  {}", fmt::join(problems, "\n  ")));
  }
}

v1::Scene ParseSceneJson(std::string_view json, const fs::path& base_dir) {
  v1::Scene scene;
  const auto status =
      google::protobuf::util::JsonStringToMessage(google::protobuf::StringPiece(json.data(), json.size()), &scene);
  if (!status.ok()) {
    throw InputError(fmt::format("not a cinevol.v1.Scene in JSON: {}", status.message().as_string()));
  }
  ApplyDefaults(scene);
  ResolvePaths(scene, base_dir);
  CheckScene(scene);
  return scene;
}

v1::Scene LoadSceneFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the scene file", path.string()));
  std::ostringstream text;
  text << in.rdbuf();
  try {
    return ParseSceneJson(text.str(), fs::absolute(path).parent_path());
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", path.string(), e.what()));
  }
}

std::string SceneToJson(const v1::Scene& scene) {
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  std::string json;
  const auto status = google::protobuf::util::MessageToJsonString(scene, &json, options);
  if (!status.ok()) throw std::runtime_error("scene to JSON: " + status.message().as_string());
  return json;
}

void SaveSceneFile(const v1::Scene& scene, const fs::path& path) {
  std::ofstream out(path, std::ios::binary);
  out << SceneToJson(scene);
  if (!out) throw InputError(fmt::format("{}: cannot write the scene file", path.string()));
}

}  // namespace cinevol

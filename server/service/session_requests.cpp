// Session request checks and event merging.
#include "service/session_requests.h"

#include <fmt/format.h>

#include "core/error.h"
#include "io/presets.h"
#include "io/scene_builder.h"
#include "io/scene_file.h"
#include "service/errors.h"

namespace cinevol::service {
namespace {

// A request past one of this server's limits; the message names the flag.
LimitExceeded OverLimit(std::string flag, const std::string& message) {
  return LimitExceeded(grpc::StatusCode::INVALID_ARGUMENT, std::move(flag), message);
}

void CheckViewport(const v1::Viewport& v, const std::string& field, const SessionLimits& limits) {
  for (auto [name, size] : {std::pair{"width", v.width()}, std::pair{"height", v.height()}}) {
    if (size < 1 || size > 8192) {
      throw InputError(fmt::format("{}.{}: {} is outside [1, 8192]", field, name, size));
    }
  }
  const std::uint64_t pixels = std::uint64_t(v.width()) * v.height();
  if (pixels > limits.max_pixels) {
    throw OverLimit("max-pixels", fmt::format("{}: {}x{} is {} pixels, over this server's limit of {} (--max-pixels)",
                                              field, v.width(), v.height(), pixels, limits.max_pixels));
  }
}

// What a streamed frame costs, against this server's limits (the scene's
// own ranges are ValidateSceneParts's). Each message names the flag.
void CheckCost(const v1::Scene& scene, const std::string& prefix, const SessionLimits& limits) {
  const v1::RenderSettings& r = scene.render();
  if (int(r.spp()) > limits.max_frame_spp) {
    throw OverLimit("max-frame-spp",
                    fmt::format("{}render.spp: {} is over this server's limit of {} per streamed frame "
                                "(--max-frame-spp; use a snapshot for more)",
                                prefix, r.spp(), limits.max_frame_spp));
  }
  const std::uint64_t samples = std::uint64_t(r.spp()) * r.width() * r.height();
  if (samples > limits.max_frame_samples) {
    throw OverLimit("max-frame-samples",
                    fmt::format("{}render.spp: {} spp at {}x{} is {} samples per frame, over this server's limit "
                                "of {} (--max-frame-samples)",
                                prefix, r.spp(), r.width(), r.height(), samples, limits.max_frame_samples));
  }
  if (int(r.max_bounces()) > limits.max_bounces) {
    throw OverLimit("max-bounces",
                    fmt::format("{}render.max_bounces: {} is over this server's limit of {} (--max-bounces)", prefix,
                                r.max_bounces(), limits.max_bounces));
  }
  if (scene.transfer_function().points_size() > limits.max_tf_points) {
    throw OverLimit("max-tf-points",
                    fmt::format("{}transfer_function.points: {} points, over this server's limit of {} "
                                "(--max-tf-points)",
                                prefix, scene.transfer_function().points_size(), limits.max_tf_points));
  }
  for (int i = 0; i < scene.labels().styles_size(); ++i) {
    const int points = scene.labels().styles(i).transfer_function().points_size();
    if (points > limits.max_tf_points) {
      throw OverLimit("max-tf-points",
                      fmt::format("{}labels.styles[{}].transfer_function.points: {} points, over this server's limit "
                                  "of {} (--max-tf-points)",
                                  prefix, i, points, limits.max_tf_points));
    }
  }
  if (scene.lights_size() > limits.max_lights) {
    throw OverLimit("max-lights", fmt::format("{}lights: {} lights, over this server's limit of {} (--max-lights)",
                                              prefix, scene.lights_size(), limits.max_lights));
  }
}

// Every problem of the scene's parts, as one InputError.
void CheckParts(const v1::Scene& scene, const std::string& prefix) {
  const std::vector<std::string> problems = ValidateSceneParts(scene);
  if (!problems.empty()) throw InputError(prefix + fmt::format("{}", fmt::join(problems, "; " + prefix)));
}

// Environment maps are files on the server: only inside the data roots.
void ResolveEnvironmentMaps(v1::Scene& scene, const VolumeRegistry& volumes) {
  for (int i = 0; i < scene.lights_size(); ++i) {
    v1::Light* light = scene.mutable_lights(i);
    if (light->has_environment() && light->environment().has_map()) {
      const auto path = volumes.ResolveDataPath(light->environment().map(),
                                                fmt::format("lights[{}].environment.map", i));
      light->mutable_environment()->set_map(path.string());
    }
  }
}

template <class Enum>
void CheckEnum(bool valid, Enum value, const std::string& field) {
  if (!valid) throw InputError(fmt::format("{}: unknown value {}", field, int(value)));
}

void CheckRange(std::uint32_t v, std::uint32_t lo, std::uint32_t hi, const std::string& field) {
  if (v < lo || v > hi) throw InputError(fmt::format("{}: {} is outside [{}, {}]", field, v, lo, hi));
}

void CheckRange(float v, float lo, float hi, const std::string& field) {
  if (!(v >= lo && v <= hi)) throw InputError(fmt::format("{}: {} is outside [{}, {}]", field, v, lo, hi));
}

DenoiseMethod ToMethod(v1::Denoiser d) {
  switch (d) {
    case v1::DENOISER_NONE: return DenoiseMethod::kNone;
    case v1::DENOISER_ACCUMULATE: return DenoiseMethod::kAccumulate;
    case v1::DENOISER_KNN: return DenoiseMethod::kKnn;
    case v1::DENOISER_GUIDED: return DenoiseMethod::kGuidedFilter;
    case v1::DENOISER_SVGF: return DenoiseMethod::kSvgf;
    default: return DenoiseMethod::kWrls;
  }
}

ChromaSubsampling ToChroma(v1::ChromaSubsampling c) {
  switch (c) {
    case v1::CHROMA_444: return ChromaSubsampling::k444;
    case v1::CHROMA_422: return ChromaSubsampling::k422;
    default: return ChromaSubsampling::k420;
  }
}

}  // namespace

void AddResolvedCamera(v1::Scene& scene, const Volume& volume, const LabelVolume* labels) {
  v1::Camera& proto = *scene.mutable_camera();
  if (proto.view() == v1::NAMED_VIEW_UNSPECIFIED) return;
  const TransferFunction tf = ResolveTransferFunction(scene.transfer_function(), volume);
  const std::vector<bool> label_blocks =
      labels ? BlocksWithVisibleLabels(volume, *labels, ResolveLabels(scene.labels(), volume)) : std::vector<bool>();
  const Camera c = ResolveCamera(proto, scene.render(), volume, tf,
                                 {ResolveClipping(scene.clipping(), volume), labels ? &label_blocks : nullptr});
  auto set = [](v1::Vec3* v, Vec3f p) {
    v->set_x(p.x);
    v->set_y(p.y);
    v->set_z(p.z);
  };
  set(proto.mutable_eye(), c.eye);
  set(proto.mutable_target(), c.eye + c.forward * c.focal_distance);
  set(proto.mutable_up(), c.up);
}

v1::Scene InitialScene(const v1::CreateSessionRequest& request, const Volume& volume, const SessionLimits& limits,
                       const VolumeRegistry& volumes) {
  if (!request.has_viewport()) throw InputError("viewport: not set");
  CheckViewport(request.viewport(), "viewport", limits);
  v1::Scene scene;
  switch (request.initial_case()) {
    case v1::CreateSessionRequest::kScene:
      scene = request.scene();
      AddDefaultLights(scene, volume);  // the answer's scene shows them
      break;
    case v1::CreateSessionRequest::kPreset:
      try {
        scene = MakePresetScene(request.preset(), volume);
      } catch (const InputError& e) {
        throw InputError(fmt::format("preset: {}", e.what()));
      }
      break;
    default: scene = MakePresetScene(DefaultPreset(volume), volume); break;
  }
  scene.clear_volume();  // the session renders volume_id
  scene.mutable_render()->set_width(request.viewport().width());
  scene.mutable_render()->set_height(request.viewport().height());
  CheckCost(scene, "scene.", limits);  // before the work of defaults and validation
  ApplyDefaults(scene);
  CheckParts(scene, "scene.");
  CheckCost(scene, "scene.", limits);
  ResolveEnvironmentMaps(scene, volumes);
  return scene;
}

FrameSettings MergeStreamSettings(FrameSettings s, const v1::StreamSettings& edit, const std::string& field) {
  CheckEnum(v1::Denoiser_IsValid(edit.denoiser()), edit.denoiser(), field + ".denoiser");
  CheckEnum(v1::ChromaSubsampling_IsValid(edit.chroma()), edit.chroma(), field + ".chroma");
  CheckEnum(v1::FinalFormat_IsValid(edit.final_format()), edit.final_format(), field + ".final_format");
  if (edit.denoiser() != v1::DENOISER_UNSPECIFIED) s.denoiser.method = ToMethod(edit.denoiser());
  if (edit.chroma() != v1::CHROMA_UNSPECIFIED) s.chroma = ToChroma(edit.chroma());
  if (edit.final_format() != v1::FINAL_FORMAT_UNSPECIFIED) s.final_png = edit.final_format() == v1::FINAL_FORMAT_PNG;
  if (edit.has_demodulate()) s.denoiser.demodulate = edit.demodulate();
  if (edit.has_jpeg_quality()) {
    CheckRange(edit.jpeg_quality(), 1, 100, field + ".jpeg_quality");
    s.jpeg_quality = static_cast<int>(edit.jpeg_quality());
  }
  if (edit.has_final_jpeg_quality()) {
    CheckRange(edit.final_jpeg_quality(), 1, 100, field + ".final_jpeg_quality");
    s.final_jpeg_quality = static_cast<int>(edit.final_jpeg_quality());
  }
  if (edit.has_target_spp()) {
    CheckRange(edit.target_spp(), 1, 65536, field + ".target_spp");
    s.target_spp = static_cast<int>(edit.target_spp());
  }
  if (edit.has_interactive_frame_ms()) {
    CheckRange(edit.interactive_frame_ms(), 0.0f, 10000.0f, field + ".interactive_frame_ms");
    s.interactive_frame_ms = edit.interactive_frame_ms();
  }
  if (edit.has_error_target()) {
    CheckRange(edit.error_target(), 0.0f, 1.0f, field + ".error_target");
    s.error_target = edit.error_target();
  }
  return s;
}

void ApplyEvent(const v1::SessionEvent& event, v1::Scene& scene, FrameSettings& settings,
                const SessionLimits& limits, const VolumeRegistry& volumes) {
  const std::string prefix = fmt::format("event {}: ", event.seq());
  v1::Scene next = scene;
  FrameSettings next_settings = settings;
  switch (event.kind_case()) {
    case v1::SessionEvent::kCamera: {
      *next.mutable_camera() = event.camera();
      ApplyDefaults(next);  // an unset fov takes its default, as in a scene file
      break;
    }
    case v1::SessionEvent::kLights:
      *next.mutable_lights() = event.lights().lights();
      ResolveEnvironmentMaps(next, volumes);
      break;
    case v1::SessionEvent::kTransferFunction:
      *next.mutable_transfer_function() = event.transfer_function();
      ApplyDefaults(next);
      break;
    case v1::SessionEvent::kRender: {
      const v1::RenderSettings& r = event.render();
      if (r.has_width() || r.has_height()) {
        throw InputError(prefix + "render.width/height: a render event cannot resize; send resize");
      }
      if (r.has_spp()) next.mutable_render()->set_spp(r.spp());
      if (r.has_max_bounces()) next.mutable_render()->set_max_bounces(r.max_bounces());
      if (r.seed() != 0) next.mutable_render()->set_seed(r.seed());
      if (r.reconstruction() != v1::RECONSTRUCTION_UNSPECIFIED) next.mutable_render()->set_reconstruction(r.reconstruction());
      break;
    }
    case v1::SessionEvent::kStream:
      try {
        next_settings = MergeStreamSettings(settings, event.stream(), "stream");
      } catch (const InputError& e) {
        throw InputError(prefix + e.what());
      }
      break;
    case v1::SessionEvent::kResize:
      try {
        CheckViewport(event.resize(), "resize", limits);
      } catch (const InputError& e) {
        throw InputError(prefix + e.what());
      }
      next.mutable_render()->set_width(event.resize().width());
      next.mutable_render()->set_height(event.resize().height());
      break;
    case v1::SessionEvent::kClipping:
      *next.mutable_clipping() = event.clipping();
      break;
    case v1::SessionEvent::kLabels:
      *next.mutable_labels() = event.labels();
      break;
    case v1::SessionEvent::kPause:
    case v1::SessionEvent::kResume:
      return;
    default:
      throw InputError(prefix + "no event kind set");
  }
  CheckCost(next, prefix, limits);
  CheckParts(next, prefix);
  scene = std::move(next);
  settings = next_settings;
}

int SnapshotSpp(const v1::SnapshotRequest& request, std::uint64_t pixels, const SessionLimits& limits) {
  CheckEnum(v1::ImageFormat_IsValid(request.format()), request.format(), "format");
  const std::uint32_t spp = request.has_spp() ? request.spp() : std::uint32_t(limits.default_snapshot_spp);
  if (spp < 1 || int(spp) > limits.max_snapshot_spp) {
    throw OverLimit("max-snapshot-spp",
                    fmt::format("spp: {} is outside [1, {}] (--max-snapshot-spp)", spp, limits.max_snapshot_spp));
  }
  if (spp * pixels > limits.max_snapshot_samples) {
    throw OverLimit("max-snapshot-samples",
                    fmt::format("spp: {} spp at {} pixels is {} samples, over this server's limit of {} "
                                "(--max-snapshot-samples)",
                                spp, pixels, spp * pixels, limits.max_snapshot_samples));
  }
  return static_cast<int>(spp);
}

}  // namespace cinevol::service

// What events do to a session's state.
#include "scene/session_state.h"

#include <fmt/format.h>

#include <algorithm>

#include "core/error.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_frame.h"
#include "scene/time_series.h"

namespace cinevol {
namespace {

void CheckViewport(const v1::Viewport& v, const std::string& field, const SessionLimits* limits) {
  for (auto [name, size] : {std::pair{"width", v.width()}, std::pair{"height", v.height()}}) {
    if (size < 1 || size > 8192) {
      throw InputError(fmt::format("{}.{}: {} is outside [1, 8192]", field, name, size));
    }
  }
  const std::uint64_t pixels = std::uint64_t(v.width()) * v.height();
  if (limits && pixels > limits->max_pixels) {
    throw OverLimit("max-pixels", fmt::format("{}: {}x{} is {} pixels, over this server's limit of {} (--max-pixels)",
                                              field, v.width(), v.height(), pixels, limits->max_pixels));
  }
}

// What a streamed frame costs, against this server's limits (the scene's
// own ranges are ValidateSceneParts's): only the parts in `parts`. Each
// message names the flag.
void CheckCost(const v1::Scene& scene, unsigned parts, const std::string& prefix, const SessionLimits& limits) {
  const v1::RenderSettings& r = scene.render();
  if ((parts & kSamplingChanged) && int(r.spp()) > limits.max_frame_spp) {
    throw OverLimit("max-frame-spp",
                    fmt::format("{}render.spp: {} is over this server's limit of {} per streamed frame "
                                "(--max-frame-spp; use a snapshot for more)",
                                prefix, r.spp(), limits.max_frame_spp));
  }
  const std::uint64_t samples = std::uint64_t(r.spp()) * r.width() * r.height();
  if ((parts & (kSamplingChanged | kCameraChanged)) && samples > limits.max_frame_samples) {
    throw OverLimit("max-frame-samples",
                    fmt::format("{}render.spp: {} spp at {}x{} is {} samples per frame, over this server's limit "
                                "of {} (--max-frame-samples)",
                                prefix, r.spp(), r.width(), r.height(), samples, limits.max_frame_samples));
  }
  if ((parts & kSamplingChanged) && int(r.max_bounces()) > limits.max_bounces) {
    throw OverLimit("max-bounces",
                    fmt::format("{}render.max_bounces: {} is over this server's limit of {} (--max-bounces)", prefix,
                                r.max_bounces(), limits.max_bounces));
  }
  if ((parts & kTransferFunctionChanged) && scene.transfer_function().points_size() > limits.max_tf_points) {
    throw OverLimit("max-tf-points",
                    fmt::format("{}transfer_function.points: {} points, over this server's limit of {} "
                                "(--max-tf-points)",
                                prefix, scene.transfer_function().points_size(), limits.max_tf_points));
  }
  for (int i = 0; (parts & kLabelsChanged) && i < scene.labels().styles_size(); ++i) {
    const int points = scene.labels().styles(i).transfer_function().points_size();
    if (points > limits.max_tf_points) {
      throw OverLimit("max-tf-points",
                      fmt::format("{}labels.styles[{}].transfer_function.points: {} points, over this server's limit "
                                  "of {} (--max-tf-points)",
                                  prefix, i, points, limits.max_tf_points));
    }
  }
  if ((parts & kFusionChanged) && scene.fusion().transfer_function().points_size() > limits.max_tf_points) {
    throw OverLimit("max-tf-points",
                    fmt::format("{}fusion.transfer_function.points: {} points, over this server's limit of {} "
                                "(--max-tf-points)",
                                prefix, scene.fusion().transfer_function().points_size(), limits.max_tf_points));
  }
  if ((parts & kLightsChanged) && scene.lights_size() > limits.max_lights) {
    throw OverLimit("max-lights", fmt::format("{}lights: {} lights, over this server's limit of {} (--max-lights)",
                                              prefix, scene.lights_size(), limits.max_lights));
  }
}

// Every problem of the scene's parts in `parts`, as one InputError.
void CheckParts(const v1::Scene& scene, unsigned parts, const std::string& prefix) {
  const std::vector<std::string> problems = ValidateSceneParts(scene, parts);
  if (!problems.empty()) throw InputError(prefix + fmt::format("{}", fmt::join(problems, "; " + prefix)));
}

void ResolveEnvironmentMaps(v1::Scene& scene, const MapResolver& resolve_map) {
  if (!resolve_map) return;
  for (int i = 0; i < scene.lights_size(); ++i) {
    v1::Light* light = scene.mutable_lights(i);
    if (light->has_environment() && light->environment().has_map()) {
      light->mutable_environment()->set_map(
          resolve_map(light->environment().map(), fmt::format("lights[{}].environment.map", i)));
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

// The scene's presets as points: its transfer function's, every label
// style's own and the second volume's (`parts`: kTransferFunctionChanged,
// kLabelsChanged, kFusionChanged).
void ExpandPresets(v1::Scene& scene, unsigned parts, const SceneContext& context) {
  const Volume& volume = context.volume;
  if ((parts & kFusionChanged) && scene.has_fusion() && context.fused) {
    v1::TransferFunction& tf = *scene.mutable_fusion()->mutable_transfer_function();
    if (tf.points_size() > 0 || !tf.preset().empty()) tf = ExpandTransferFunction(tf, *context.fused);
  }
  if (parts & kTransferFunctionChanged) {
    *scene.mutable_transfer_function() = ExpandTransferFunction(scene.transfer_function(), volume);
  }
  for (int i = 0; (parts & kLabelsChanged) && i < scene.labels().styles_size(); ++i) {
    v1::LabelStyle* style = scene.mutable_labels()->mutable_styles(i);
    if (style->has_transfer_function()) {
      *style->mutable_transfer_function() = ExpandTransferFunction(style->transfer_function(), volume);
    }
  }
}

// Label styles need a segmentation; table removal does not. `began`: the
// session exists already (its volume is as it was when it began).
void CheckSegmentation(const v1::Labels& labels, const SceneContext& context, const std::string& field, bool began) {
  if (!StylesLabels(labels) || (context.labels && context.labels->segmentation)) return;
  throw InputError(began ? fmt::format("{}: volume '{}' had no segmentation when this session began; load one "
                                       "(LoadLabels) and start a new session",
                                       field, context.volume_id)
                         : fmt::format("{}: volume '{}' has no segmentation; load one first (LoadLabels, or an "
                                       "upload with header.labels_for)",
                                       field, context.volume_id));
}

// A DICOM SEG's recommended display colours as the labels' styles, where the
// scene styles no label: segments show as their makers coloured them, as in
// other viewers. A scene that styles labels keeps its own.
// Scene.fusion against the second volume the session began with: that
// volume, in the same Frame of Reference unless aligned by patient
// coordinates on request, with SUVbw where asked.
void CheckFusion(const v1::Fusion& fusion, const SceneContext& context, const std::string& field) {
  const std::string& id = fusion.volume_id();
  if (!context.fused || id != context.fused_id) {
    throw InputError(
        fmt::format("{}.volume_id: '{}' is not this session's second volume{}; the second volume is "
                    "chosen when the session is created (docs/time-and-fusion.md)",
                    field, id, context.fused ? " ('" + context.fused_id + "')" : std::string(" (none)")));
  }
  const std::string& ours = context.volume.metadata().frame_of_reference_uid;
  const std::string& theirs = context.fused->metadata().frame_of_reference_uid;
  if (!fusion.align_by_patient() && (ours.empty() || theirs != ours)) {
    throw InputError(
        fmt::format("{}.align_by_patient: volume '{}' is in Frame of Reference {}, the volume in {}: "
                    "their patient coordinates need not be one space; set align_by_patient to place it "
                    "by its patient coordinates as they are",
                    field, id, theirs.empty() ? "(none given)" : theirs, ours.empty() ? "(none given)" : ours));
  }
  const VolumeMetadata& fused = context.fused->metadata();
  if (fusion.suv() && !(fused.suv_factor > 0)) {
    throw InputError(fmt::format(
        "{}.suv: volume '{}' has no SUVbw: {}", field, id,
        fused.suv_refused.empty() ? "it is no PET with the DICOM attributes SUVbw needs" : fused.suv_refused));
  }
  if (fusion.suv() && fusion.transfer_function().points_size() == 0 && !fusion.transfer_function().preset().empty()) {
    throw InputError(field +
                     ".transfer_function.preset: a preset is in the volume's own values; with suv give "
                     "points in SUVbw");
  }
}

void AddRecommendedColours(v1::Scene& scene, const SceneContext& context) {
  if (!context.labels || context.labels->colors.empty() || scene.labels().styles_size() > 0) return;
  for (const auto& [value, rgb] : context.labels->colors) {
    v1::LabelStyle& style = *scene.mutable_labels()->add_styles();
    style.set_value(std::uint32_t(value));
    style.mutable_color()->set_r(rgb.x);
    style.mutable_color()->set_g(rgb.y);
    style.mutable_color()->set_b(rgb.z);
  }
}

void SetVec(v1::Vec3* v, Vec3f p) {
  v->set_x(p.x);
  v->set_y(p.y);
  v->set_z(p.z);
}

// A named view as numbers (eye, target, up; `view` cleared): turned about
// the camera's target at its distance, which reads no voxel, or where there
// is no eye and target (a new session's scene), framing what the scene shows
// (the transfer function's blocks, and every label voxel where a label is
// hidden: a scan of the volume).
void ResolveNamedView(v1::Scene& scene, const SceneContext& context) {
  v1::Camera& proto = *scene.mutable_camera();
  if (proto.view() == v1::NAMED_VIEW_UNSPECIFIED) return;
  const Volume& volume = context.volume;
  TransferFunction tf;
  InView in_view;
  std::vector<bool> label_blocks;
  if (!(proto.has_eye() && proto.has_target())) {
    tf = ResolveTransferFunction(scene.transfer_function(), volume);
    in_view.clip = ResolveClipping(scene.clipping(), volume);
    if (context.labels) {
      label_blocks = BlocksWithVisibleLabels(volume, *context.labels, ResolveLabels(scene.labels(), volume));
      in_view.label_blocks = &label_blocks;
    }
  }
  // The target at the framed (or kept) distance, not at the lens's focal
  // distance: that may be anything above 0, and 1e-12 mm put it onto the eye.
  v1::Camera framed = proto;
  framed.clear_focal_distance_mm();
  const Camera c = ResolveCamera(framed, scene.render(), volume, tf, in_view);
  SetVec(proto.mutable_eye(), c.eye);
  SetVec(proto.mutable_target(), c.eye + c.forward * c.focal_distance);
  SetVec(proto.mutable_up(), c.up);
  proto.clear_view();
}

// Edits the scene part the event names (PartsOf says which).
void ApplyToScene(const v1::SessionEvent& event, v1::Scene& scene, const std::string& prefix) {
  switch (event.kind_case()) {
    case v1::SessionEvent::kCamera: {
      const v1::Camera& camera = event.camera();
      if (camera.view() != v1::NAMED_VIEW_UNSPECIFIED && !(camera.has_eye() && camera.has_target())) {
        // A view button turns about the current target at its distance (as
        // Slicer's do), never framing: that would read the volume on the
        // thread that read the event.
        const v1::Vec3 eye = scene.camera().eye(), target = scene.camera().target();
        *scene.mutable_camera() = camera;
        *scene.mutable_camera()->mutable_eye() = eye;
        *scene.mutable_camera()->mutable_target() = target;
      } else {
        *scene.mutable_camera() = camera;
      }
      break;
    }
    case v1::SessionEvent::kLights:
      *scene.mutable_lights() = event.lights().lights();
      break;
    case v1::SessionEvent::kTransferFunction:
      *scene.mutable_transfer_function() = event.transfer_function();
      break;
    case v1::SessionEvent::kRender: {
      const v1::RenderSettings& r = event.render();
      if (r.has_width() || r.has_height()) {
        throw InputError(prefix + "render.width/height: a render event cannot resize; send resize");
      }
      // Set fields change (a seed of 0 and an unspecified reconstruction are unset).
      v1::RenderSettings* to = scene.mutable_render();
      if (r.has_spp()) to->set_spp(r.spp());
      if (r.has_max_bounces()) to->set_max_bounces(r.max_bounces());
      if (r.seed() != 0) to->set_seed(r.seed());
      if (r.reconstruction() != v1::RECONSTRUCTION_UNSPECIFIED) to->set_reconstruction(r.reconstruction());
      break;
    }
    case v1::SessionEvent::kResize:
      scene.mutable_render()->set_width(event.resize().width());
      scene.mutable_render()->set_height(event.resize().height());
      break;
    case v1::SessionEvent::kClipping:
      *scene.mutable_clipping() = event.clipping();
      break;
    case v1::SessionEvent::kLabels:
      *scene.mutable_labels() = event.labels();
      break;
    case v1::SessionEvent::kFusion:
      if (event.fusion().volume_id().empty()) {
        scene.clear_fusion();
      } else {
        *scene.mutable_fusion() = event.fusion();
      }
      break;
    default:
      break;
  }
}

// The parts of `scene` that `parts` names, alone: what an edit of them
// replaces, kept to put back if the edit is refused.
v1::Scene CopyParts(const v1::Scene& scene, unsigned parts) {
  v1::Scene copy;
  if (parts & kCameraChanged) *copy.mutable_camera() = scene.camera();
  if (parts & (kCameraChanged | kSamplingChanged)) *copy.mutable_render() = scene.render();
  if (parts & kLightsChanged) *copy.mutable_lights() = scene.lights();
  if (parts & kTransferFunctionChanged) *copy.mutable_transfer_function() = scene.transfer_function();
  if (parts & kClippingChanged) *copy.mutable_clipping() = scene.clipping();
  if (parts & kLabelsChanged) *copy.mutable_labels() = scene.labels();
  if ((parts & kFusionChanged) && scene.has_fusion()) *copy.mutable_fusion() = scene.fusion();
  return copy;
}

void RestoreParts(v1::Scene& scene, v1::Scene& saved, unsigned parts) {
  if (parts & kCameraChanged) scene.mutable_camera()->Swap(saved.mutable_camera());
  if (parts & (kCameraChanged | kSamplingChanged)) scene.mutable_render()->Swap(saved.mutable_render());
  if (parts & kLightsChanged) scene.mutable_lights()->Swap(saved.mutable_lights());
  if (parts & kTransferFunctionChanged) scene.mutable_transfer_function()->Swap(saved.mutable_transfer_function());
  if (parts & kClippingChanged) scene.mutable_clipping()->Swap(saved.mutable_clipping());
  if (parts & kLabelsChanged) scene.mutable_labels()->Swap(saved.mutable_labels());
  if (parts & kFusionChanged) {
    if (saved.has_fusion()) {
      scene.mutable_fusion()->Swap(saved.mutable_fusion());
    } else {
      scene.clear_fusion();
    }
  }
}

// The scene parts an event edits: its SceneChange bits.
unsigned PartsOf(const v1::SessionEvent& event) {
  switch (event.kind_case()) {
    case v1::SessionEvent::kCamera:
    case v1::SessionEvent::kResize:
      return kCameraChanged;
    case v1::SessionEvent::kLights:
      return kLightsChanged;
    case v1::SessionEvent::kTransferFunction:
      return kTransferFunctionChanged;
    case v1::SessionEvent::kRender:
      return kSamplingChanged;
    case v1::SessionEvent::kClipping:
      return kClippingChanged;
    case v1::SessionEvent::kLabels:
      return kLabelsChanged;
    case v1::SessionEvent::kFusion:
      return kFusionChanged;
    default:
      return 0;
  }
}

}  // namespace

void CheckStreamSettings(const v1::StreamSettings& edit, const std::string& field) {
  CheckEnum(v1::Denoiser_IsValid(edit.denoiser()), edit.denoiser(), field + ".denoiser");
  CheckEnum(v1::ChromaSubsampling_IsValid(edit.chroma()), edit.chroma(), field + ".chroma");
  CheckEnum(v1::FinalFormat_IsValid(edit.final_format()), edit.final_format(), field + ".final_format");
  if (edit.has_jpeg_quality()) CheckRange(edit.jpeg_quality(), 1, 100, field + ".jpeg_quality");
  if (edit.has_final_jpeg_quality()) CheckRange(edit.final_jpeg_quality(), 1, 100, field + ".final_jpeg_quality");
  if (edit.has_target_spp()) CheckRange(edit.target_spp(), 1, 65536, field + ".target_spp");
  if (edit.has_interactive_frame_ms()) {
    CheckRange(edit.interactive_frame_ms(), 0.0f, 10000.0f, field + ".interactive_frame_ms");
  }
  if (edit.has_error_target()) CheckRange(edit.error_target(), 0.0f, 1.0f, field + ".error_target");
}

v1::SessionState InitialState(const v1::CreateSessionRequest& request, const SceneContext& context,
                              const SessionLimits& limits) {
  if (!request.has_viewport()) throw InputError("viewport: not set");
  CheckViewport(request.viewport(), "viewport", &limits);
  CheckStreamSettings(request.stream(), "stream");
  const Volume& volume = context.volume;
  v1::SessionState state;
  v1::Scene& scene = *state.mutable_scene();
  switch (request.initial_case()) {
    case v1::CreateSessionRequest::kScene:
      scene = request.scene();
      ToVolumeFrame(scene, VolumePlacement::Of(volume));  // sessions hold the renderers' frame
      AddDefaultLights(scene, volume);                    // the answer's scene shows them
      break;
    case v1::CreateSessionRequest::kPreset:
      try {
        scene = MakePresetScene(request.preset(), volume);
      } catch (const InputError& e) {
        throw InputError(fmt::format("preset: {}", e.what()));
      }
      break;
    default:
      scene = MakePresetScene(DefaultPreset(volume), volume);
      break;
  }
  scene.clear_volume();                                          // the session renders volume_id
  if (scene.fusion().volume_id().empty()) scene.clear_fusion();  // a fusion names its volume
  scene.mutable_render()->set_width(request.viewport().width());
  scene.mutable_render()->set_height(request.viewport().height());
  CheckCost(scene, kEverythingChanged, "scene.", limits);  // before the work of defaults and validation
  ApplyDefaults(scene);
  CheckParts(scene, kEverythingChanged, "scene.");
  CheckSegmentation(scene.labels(), context, "scene.labels", false);
  CheckTime(scene.time(), context.phases, "scene.time");
  if (scene.has_fusion()) CheckFusion(scene.fusion(), context, "scene.fusion");
  AddRecommendedColours(scene, context);
  ExpandPresets(scene, kEverythingChanged, context);
  CheckCost(scene, kEverythingChanged, "scene.", limits);
  ResolveEnvironmentMaps(scene, context.resolve_map);
  ResolveNamedView(scene, context);  // after the presets: it frames what they show
  *state.mutable_viewport() = request.viewport();
  *state.mutable_stream() = request.stream();
  *state.mutable_placement() = PlacementMessage(volume);
  return state;
}

void ResolveSceneModel(v1::Scene& scene, const SceneContext& context) {
  ExpandPresets(scene, kEverythingChanged, context);
  ResolveNamedView(scene, context);
}

unsigned ApplyEvent(v1::SessionState& state, const v1::SessionEvent& event, const SceneContext& context,
                    const SessionLimits* limits) {
  const std::string prefix = fmt::format("event {}: ", event.seq());
  auto with_prefix = [&](auto check) {
    try {
      check();
    } catch (const OverLimit& e) {
      throw OverLimit(e.flag(), prefix + e.what());
    } catch (const InputError& e) {
      throw InputError(prefix + e.what());
    }
  };
  unsigned changes = 0;
  switch (event.kind_case()) {
    case v1::SessionEvent::kPause:
      changes = state.paused() ? 0u : unsigned(kPauseChanged);
      state.set_paused(true);
      break;
    case v1::SessionEvent::kResume:
      changes = state.paused() ? unsigned(kPauseChanged) : 0u;
      state.set_paused(false);
      break;
    case v1::SessionEvent::kStream:
      with_prefix([&] { CheckStreamSettings(event.stream(), "stream"); });
      state.mutable_stream()->MergeFrom(event.stream());  // set fields change
      changes = kStreamChanged;
      break;
    case v1::SessionEvent::kMeasurements: {
      // Shared at once, beside the event queue: the newest event applied stays as it was.
      const std::vector<std::string> problems = ValidateMeasurements(event.measurements().measurements());
      if (!problems.empty()) throw InputError(prefix + problems.front());
      *state.mutable_scene()->mutable_measurements() = event.measurements().measurements();
      return kMeasurementsChanged;
    }
    case v1::SessionEvent::kTime:
      with_prefix([&] { CheckTime(event.time(), context.phases, "time"); });
      *state.mutable_scene()->mutable_time() = event.time();
      return kPhaseChanged;
    case v1::SessionEvent::kPointer:
      throw InputError(prefix + "pointer: a pointer is its sender's (ApplyPointer)");
    case v1::SessionEvent::KIND_NOT_SET:
      throw InputError(prefix + "no event kind set");
    default: {
      // Edited in place, only the parts it touches checked; put back if refused.
      if (event.has_resize()) with_prefix([&] { CheckViewport(event.resize(), "resize", limits); });
      v1::Scene& scene = *state.mutable_scene();
      changes = PartsOf(event);
      v1::Scene saved = CopyParts(scene, changes);
      try {
        ApplyToScene(event, scene, prefix);
        ApplyDefaults(scene, changes);  // an unset fov takes its default, as in a scene file
        if (changes & kLightsChanged) ResolveEnvironmentMaps(scene, context.resolve_map);
        CheckParts(scene, changes, prefix);
        if (changes & kLabelsChanged) {
          with_prefix([&] { CheckSegmentation(scene.labels(), context, "labels", true); });
        }
        if ((changes & kFusionChanged) && scene.has_fusion()) {
          with_prefix([&] { CheckFusion(scene.fusion(), context, "fusion"); });
        }
        ExpandPresets(scene, changes, context);
        if (limits) CheckCost(scene, changes, prefix, *limits);
        if (changes & kCameraChanged) ResolveNamedView(scene, context);
      } catch (...) {
        RestoreParts(scene, saved, changes);
        throw;
      }
      if (event.has_resize()) *state.mutable_viewport() = event.resize();
      // An event that leaves its parts as they were changes nothing: a view
      // held still keeps its samples when a client sends its camera again
      // (a pointer move of no pixel) or an unchanged edit. Bytes compared:
      // where they differ for equal parts (a -0 for a 0) the event restarts
      // the view, as every event did before.
      if (saved.SerializeAsString() == CopyParts(scene, changes).SerializeAsString()) changes = 0;
    }
  }
  state.set_last_event_seq(std::max(state.last_event_seq(), event.seq()));
  return changes;
}

unsigned ApplyPointer(v1::SessionState& state, const std::string& who, const v1::Pointer& pointer) {
  if (!(pointer.x() >= 0 && pointer.x() <= 1 && pointer.y() >= 0 && pointer.y() <= 1)) {
    throw InputError(fmt::format("pointer: ({}, {}) is outside the frame, [0, 1] each way", pointer.x(), pointer.y()));
  }
  if (pointer.hidden()) return HidePointer(state, who);
  auto& pointers = *state.mutable_pointers();
  // Listed by who, each once.
  auto at = std::lower_bound(pointers.begin(), pointers.end(), who,
                             [](const v1::SharedPointer& p, const std::string& w) { return p.who() < w; });
  if (at == pointers.end() || at->who() != who) {
    const int index = int(at - pointers.begin());
    pointers.Add()->set_who(who);
    for (int i = pointers.size() - 1; i > index; --i) pointers.SwapElements(i, i - 1);
    at = pointers.begin() + index;
  } else if (at->x() == pointer.x() && at->y() == pointer.y()) {
    return 0;
  }
  at->set_x(pointer.x());
  at->set_y(pointer.y());
  return kPointersChanged;
}

unsigned HidePointer(v1::SessionState& state, const std::string& who) {
  auto& pointers = *state.mutable_pointers();
  const auto shown = std::find_if(pointers.begin(), pointers.end(), [&](const auto& p) { return p.who() == who; });
  if (shown == pointers.end()) return 0;
  pointers.erase(shown);
  return kPointersChanged;
}

void CoalesceEvent(std::map<int, v1::SessionEvent>& waiting, const v1::SessionEvent& event) {
  auto [it, fresh] = waiting.try_emplace(int(event.kind_case()), event);
  if (fresh) return;
  if (event.has_render() || event.has_stream()) {
    it->second.MergeFrom(event);  // set fields change; the seq is the newest
  } else {
    it->second = event;
  }
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

v1::CreateSessionRequest RecreateRequest(const v1::SessionState& state, const std::string& volume_id) {
  v1::CreateSessionRequest request;
  request.set_volume_id(volume_id);
  *request.mutable_viewport() = state.viewport();
  *request.mutable_scene() = state.scene();
  *request.mutable_stream() = state.stream();
  return request;
}

}  // namespace cinevol

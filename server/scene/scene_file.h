// Scene files: the proto3 JSON form of cinevol.v1.Scene. Loading fills the
// documented defaults and validates every field; problems name the field in
// its JSON spelling (e.g. "camera.up", "transferFunction.points[2].opacity").
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

// What validation takes of values at the extremes (docs/rendering.md,
// "Values at the extremes"): every position and vector component, and the
// camera's aperture and focal distance, within +-kMaxSceneMm (a thousand km:
// past it float positions are metres apart and squared lengths overflow);
// directions at least kMinDirectionLength long (shorter ones square to 0);
// a light's colour x intensity, per channel, and transfer-function emission
// at most kMaxRadiance, so that sums over samples and frames stay finite.
inline constexpr float kMaxSceneMm = 1e9f;
inline constexpr float kMinDirectionLength = 1e-6f;
inline constexpr float kMaxRadiance = 1e12f;

// Parses, fills defaults and validates; throws InputError listing every
// problem. Relative volume and environment-map paths are resolved against
// `base_dir` (left as they are when it is empty).
v1::Scene ParseSceneJson(std::string_view json, const std::filesystem::path& base_dir = {});

// ParseSceneJson on a file's contents, relative paths against its folder.
v1::Scene LoadSceneFile(const std::filesystem::path& path);

std::string SceneToJson(const v1::Scene& scene);
void SaveSceneFile(const v1::Scene& scene, const std::filesystem::path& path);

// The parts of a scene, as what an edit changes: a session's events report
// them (session_state.h) and FramePipeline::Update acts on them.
enum SceneChange : unsigned {
  kCameraChanged = 1u << 0,  // the camera or the frame's size
  kTransferFunctionChanged = 1u << 1,
  kLightsChanged = 1u << 2,
  kSamplingChanged = 1u << 3,  // spp, bounces, seed or reconstruction
  kClippingChanged = 1u << 4,  // the crop box or clip planes
  kLabelsChanged = 1u << 5,    // the label styles or table removal
  kFusionChanged = 1u << 6,    // the second volume or how it shows (Scene.fusion)
  kEverythingChanged = (1u << 7) - 1,
  // What the picture shows (not only how it is sampled): the denoiser's cue.
  kPictureChanges =
      kCameraChanged | kTransferFunctionChanged | kLightsChanged | kClippingChanged | kLabelsChanged | kFusionChanged,
};

// Scene.measurements: how many, and a name's length at most.
inline constexpr int kMaxMeasurements = 64;
inline constexpr std::size_t kMaxMeasurementName = 64;

// Sets every absent `optional` field to its documented default, in the
// parts given (SceneChange bits; all by default).
void ApplyDefaults(v1::Scene& scene, unsigned parts = kEverythingChanged);

// Every problem found, one message each, naming the field; empty when valid.
std::vector<std::string> ValidateScene(const v1::Scene& scene);
// The same for the parts given (SceneChange bits), without the volume
// source (a session names its volume apart).
std::vector<std::string> ValidateSceneParts(const v1::Scene& scene, unsigned parts = kEverythingChanged);

// The problems of a list of measurements (Scene.measurements, a measurements event).
std::vector<std::string> ValidateMeasurements(const google::protobuf::RepeatedPtrField<v1::Measurement>& measurements);
// Whether `labels` styles a segmentation's labels (styles, show_unlisted),
// which needs one; remove_table alone does not.
bool StylesLabels(const v1::Labels& labels);
// Throws InputError listing ValidateScene's problems, if any.
void CheckScene(const v1::Scene& scene);

}  // namespace cinevol

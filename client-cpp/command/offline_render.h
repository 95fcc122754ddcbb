// Rendering a scene to an image file without a server: `cinevol render`.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "cinevol/v1/scene.pb.h"
#include "core/labels.h"
#include "render/renderer.h"

namespace cinevol::cli {

struct OfflineRenderResult {
  std::string backend;
  int frames = 0;
  int total_spp = 0;
  double seconds = 0;      // rendering only, volume loading excluded
  double load_seconds = 0;
  double paths_per_second = 0;
  float estimated_error = -1;  // the still's estimated relative error; < 0: too few frames to tell
  std::string table;       // where the scene removes the table: what the search found
};

// A scene's volume and segmentation loaded as offline commands (render,
// pick, slice) read them, and the scene in the volume-centred frame the renderers
// work in.
struct OfflineScene {
  std::shared_ptr<const Volume> volume;
  std::shared_ptr<const LabelVolume> labels;  // null with neither a segmentation nor table removal
  v1::Scene scene;
};

// Throws InputError where the scene styles labels but names no segmentation.
OfflineScene LoadOfflineScene(const v1::Scene& scene, const std::filesystem::path& base_dir);

// Where an offline command's scene comes from: a scene file, or a volume
// (a file or a DICOM folder) opened as a new session on it would be: its
// preset (the volume's default where none is given), framed from the
// preset's named view, lit by the volume's default lights.
struct SceneSource {
  std::string scene_file;   // --scene
  std::string volume_path;  // --volume
  std::string preset;       // --preset, with --volume
  int width = 1024, height = 768;  // --width, --height, with --volume
  bool remove_table = false;       // sets the scene's labels.removeTable (render's --remove-table)
  bool resample_uneven = false;    // --resample-uneven, with --volume (a DICOM folder)
};
// Which flags of SceneSource a command takes besides --scene and --volume.
enum class SceneFlags {
  kWithPresetAndSize,    // --preset (the transfer function's), --width, --height
  kWithoutPresetOrSize,  // a slice has a size of its own, and a --preset of its window's
};
// Adds --scene and --volume (one of them required) and `flags` to `cmd`.
void AddSceneSource(CLI::App* cmd, SceneSource& source, SceneFlags flags);
// The source's scene, its volume loaded once.
OfflineScene LoadOfflineScene(const SceneSource& source);

// Renders `loaded`'s still as a session's view refines when it rests:
// frames of the scene's spp, denoised and blended with their accumulation by
// estimated error, until the estimated relative error is at most
// `error_target` (0: never) or `total_spp` samples per pixel; then writes
// `out`: .exr/.pfm linear radiance, .png/.jpg tone-mapped sRGB with the
// camera's exposure.
OfflineRenderResult RenderToFile(OfflineScene loaded, int total_spp, float error_target, Backend backend,
                                 const std::filesystem::path& out);

// Throws InputError unless `out` names an image type WriteImage writes: checked
// before a volume is loaded, so a typo costs nothing.
void CheckImageName(const std::filesystem::path& out);
// Writes an image by extension (see RenderToFile); throws InputError for others.
void WriteImage(const ImageRgbF& linear, float exposure, const std::filesystem::path& out);

}  // namespace cinevol::cli

// Rendering a scene to an image file without a server: `cinevol render`.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

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

// Loads the scene's volume (LoadOfflineScene), renders `total_spp` samples per pixel in frames of
// the scene's spp, and writes `out`: .exr/.pfm linear radiance, .png/.jpg
// tone-mapped sRGB with the camera's exposure.
OfflineRenderResult RenderToFile(const v1::Scene& scene, const std::filesystem::path& base_dir, int total_spp,
                                 Backend backend, const std::filesystem::path& out);

// Writes an image by extension (see RenderToFile); throws InputError for others.
void WriteImage(const ImageRgbF& linear, float exposure, const std::filesystem::path& out);

}  // namespace cinevol::cli

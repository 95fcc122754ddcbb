// RenderToFile: load, then accumulate through the frame pipeline, write.
#include "offline_render.h"

#include <chrono>
#include <cstdio>

#include <fmt/format.h>

#include "core/error.h"
#include "core/tone_map.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "io/label_volume.h"
#include "scene/presets.h"
#include "scene/scene_frame.h"
#include "io/volume_loader.h"
#include "pipeline/frame_pipeline.h"

namespace cinevol::cli {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

void WriteImage(const ImageRgbF& linear, float exposure, const std::filesystem::path& out) {
  const std::string ext = Lower(out.extension().string());
  if (ext == ".exr") {
    WriteExr(out, linear);
  } else if (ext == ".pfm") {
    WritePfm(out, linear);
  } else if (ext == ".png") {
    WriteFile(out, EncodePng(ToneMap(linear, exposure)));
  } else if (ext == ".jpg" || ext == ".jpeg") {
    WriteFile(out, EncodeJpeg(ToneMap(linear, exposure), 92));
  } else {
    throw InputError(fmt::format("{}: unknown image type; use .exr, .pfm, .png or .jpg", out.string()));
  }
}

SceneVolume LoadSceneVolume(const v1::Scene& scene, const std::filesystem::path& base_dir) {
  SceneVolume loaded;
  loaded.volume = std::make_shared<const Volume>(LoadVolume(scene.volume(), base_dir));
  if (StylesLabels(scene.labels()) && scene.volume().labels().empty()) {
    throw InputError("labels: the scene styles labels but volume.labels names no segmentation");
  }
  loaded.labels = LoadSceneLabels(scene, *loaded.volume, base_dir);  // with the table where it removes it
  return loaded;
}

OfflineRenderResult RenderToFile(const v1::Scene& scene, const std::filesystem::path& base_dir, int total_spp,
                                 Backend backend, const std::filesystem::path& out) {
  OfflineRenderResult result;
  const auto load_start = std::chrono::steady_clock::now();
  const auto [volume, labels] = LoadSceneVolume(scene, base_dir);
  if (scene.labels().remove_table()) result.table = labels ? labels->table_note : "";
  v1::Scene lit = scene;
  ToVolumeFrame(lit, VolumePlacement::Of(*volume));  // the renderers' frame
  if (AddDefaultLights(lit, *volume)) {
    std::fprintf(stderr, "cinevol: the scene has no lights: rendering with the volume's default lights (a key light "
                         "and a sky)\n");
  }
  FramePipeline pipeline(backend, volume, {}, labels);
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  settings.target_spp = total_spp;
  pipeline.Update(lit, settings);
  result.load_seconds = SecondsSince(load_start);
  result.backend = ToString(pipeline.backend());

  const int frame_spp = static_cast<int>(scene.render().spp());
  const auto start = std::chrono::steady_clock::now();
  while (!pipeline.Converged()) {
    pipeline.Accumulate(std::min(frame_spp, total_spp - pipeline.accumulated_spp()));
    ++result.frames;
  }
  const ImageRgbF image = pipeline.AccumulatedRadiance();
  result.total_spp = pipeline.accumulated_spp();
  result.seconds = SecondsSince(start);
  result.paths_per_second = double(result.total_spp) * image.width * image.height / result.seconds;
  WriteImage(image, pipeline.exposure(), out);
  return result;
}

}  // namespace cinevol::cli

// RenderToFile: load, then accumulate through the frame pipeline, write.
#include "offline_render.h"

#include "commands.h"

#include <chrono>
#include <cstdio>

#include <fmt/format.h>

#include "core/error.h"
#include "core/tone_map.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "io/label_volume.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "scene/session_state.h"
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

void CheckImageName(const std::filesystem::path& out) {
  const std::string ext = Lower(out.extension().string());
  if (ext != ".exr" && ext != ".pfm" && ext != ".png" && ext != ".jpg" && ext != ".jpeg") {
    throw InputError(fmt::format("{}: unknown image type; use .exr, .pfm, .png or .jpg", out.string()));
  }
}

void WriteImage(const ImageRgbF& linear, float exposure, const std::filesystem::path& out) {
  CheckImageName(out);
  const std::string ext = Lower(out.extension().string());
  if (ext == ".exr") {
    WriteExr(out, linear);
  } else if (ext == ".pfm") {
    WritePfm(out, linear);
  } else if (ext == ".png") {
    WriteFile(out, EncodePng(ToneMap(linear, exposure)));
  } else {
    WriteFile(out, EncodeJpeg(ToneMap(linear, exposure), 92));
  }
}

namespace {

// `loaded`'s volume, scene (in patient coordinates) and segmentation made ready for the renderers.
OfflineScene Finish(OfflineScene loaded, const std::filesystem::path& base_dir) {
  const v1::Scene& scene = loaded.scene;
  if (StylesLabels(scene.labels()) && scene.volume().labels().empty()) {
    throw InputError("labels: the scene styles labels but volume.labels names no segmentation");
  }
  loaded.labels = LoadSceneLabels(scene, *loaded.volume, base_dir);  // with the table where it removes it
  ToVolumeFrame(loaded.scene, VolumePlacement::Of(*loaded.volume));  // the renderers' frame
  // A named view frames what the scene shows, labels and table removal included, as a session's does.
  ResolveSceneModel(loaded.scene, {*loaded.volume, loaded.labels.get()});
  return loaded;
}

}  // namespace

OfflineScene LoadOfflineScene(const v1::Scene& scene, const std::filesystem::path& base_dir) {
  OfflineScene loaded;
  loaded.volume = std::make_shared<const Volume>(LoadVolume(scene.volume(), base_dir));
  loaded.scene = scene;
  return Finish(std::move(loaded), base_dir);
}

void AddSceneSource(CLI::App* cmd, SceneSource& source, SceneFlags flags) {
  auto* scene = cmd->add_option("--scene", source.scene_file, "Scene file (JSON of cinevol.v1.Scene)");
  auto* volume = cmd->add_option("--volume", source.volume_path,
                                 "Instead of --scene: a volume file or DICOM folder, shown as a new session shows it");
  scene->excludes(volume);
  cmd->add_flag("--resample-uneven", source.resample_uneven, kResampleUnevenHelp)->needs(volume);
  if (flags == SceneFlags::kWithPresetAndSize) {
    cmd->add_option("--preset", source.preset, "With --volume: the transfer-function preset (default: the volume's)")
        ->needs(volume);
    cmd->add_option("--width", source.width, "With --volume: the image's width (default 1024)")
        ->check(CLI::Range(1, 8192))
        ->needs(volume);
    cmd->add_option("--height", source.height, "With --volume: the image's height (default 768)")
        ->check(CLI::Range(1, 8192))
        ->needs(volume);
  }
}

OfflineScene LoadOfflineScene(const SceneSource& source) {
  if (source.scene_file.empty() == source.volume_path.empty()) throw InputError("give --scene FILE or --volume PATH");
  if (!source.scene_file.empty()) {
    v1::Scene scene = LoadSceneFile(source.scene_file);
    if (source.remove_table) scene.mutable_labels()->set_remove_table(true);
    return LoadOfflineScene(scene, {});
  }
  v1::VolumeSource from;
  if (std::filesystem::is_directory(source.volume_path)) {
    from.set_dicom_folder(source.volume_path);
    from.set_resample_uneven(source.resample_uneven);
  } else {
    from.set_file(source.volume_path);
  }
  OfflineScene loaded;
  loaded.volume = std::make_shared<const Volume>(LoadVolume(from));
  loaded.scene = MakePresetScene(source.preset.empty() ? DefaultPreset(*loaded.volume) : source.preset, *loaded.volume);
  loaded.scene.mutable_render()->set_width(std::uint32_t(source.width));
  loaded.scene.mutable_render()->set_height(std::uint32_t(source.height));
  ApplyDefaults(loaded.scene);
  if (const std::string misfit = PresetMisfit(source.preset, *loaded.volume); !misfit.empty()) {
    std::fprintf(stderr, "cinevol: %s\n", misfit.c_str());
  }
  *loaded.scene.mutable_volume() = from;
  if (source.remove_table) loaded.scene.mutable_labels()->set_remove_table(true);
  return Finish(std::move(loaded), {});
}

OfflineRenderResult RenderToFile(OfflineScene loaded, int total_spp, float error_target, Backend backend,
                                 const std::filesystem::path& out) {
  OfflineRenderResult result;
  if (loaded.scene.labels().remove_table()) result.table = loaded.labels ? loaded.labels->table_note : "";
  v1::Scene& lit = loaded.scene;
  if (AddDefaultLights(lit, *loaded.volume)) {
    std::fprintf(stderr, "cinevol: the scene has no lights: rendering with the volume's default lights (a key light "
                         "and a sky)\n");
  }
  // The still a session ends with when its view rests: frames of the scene's
  // spp, denoised, blended with their accumulation by estimated error
  // (pipeline/refine.h) until the error target or total_spp.
  FramePipeline pipeline(backend, loaded.volume, {}, loaded.labels);
  FrameSettings settings;
  settings.target_spp = total_spp;
  settings.error_target = error_target;
  pipeline.Update(lit, settings);
  result.backend = ToString(pipeline.backend());

  const auto start = std::chrono::steady_clock::now();
  while (!pipeline.Converged()) {
    result.estimated_error = pipeline.RenderFrame().estimated_error;
    ++result.frames;
  }
  ImageRgbF image = pipeline.RefinedRadiance();
  if (image.width == 0) image = pipeline.DenoisedRadiance();  // too few frames to blend: what the view showed
  result.total_spp = pipeline.accumulated_spp();
  result.seconds = SecondsSince(start);
  result.paths_per_second = double(result.total_spp) * image.width * image.height / result.seconds;
  WriteImage(image, pipeline.exposure(), out);
  return result;
}

}  // namespace cinevol::cli

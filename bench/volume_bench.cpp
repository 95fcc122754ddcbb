// cinevol-bench volume: what a volume costs before it renders: loading, the
// summaries every volume keeps (histogram, block value ranges), judging its
// kind and framing its default view.
#include <fmt/format.h>

#include <chrono>

#include "bench.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "scene/volume_kind.h"
#include "io/volume_loader.h"

namespace cinevol::bench {
namespace {

template <class F>
double Milliseconds(F&& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::string Row(const std::string& spec) {
  std::shared_ptr<const Volume> volume;
  const double load = Milliseconds([&] { volume = std::make_shared<const Volume>(LoadVolume(ParseVolumeSpec(spec))); });
  std::vector<float> values(volume->voxel_count());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = volume->ValueAtIndex(i);
  const double construct =
      Milliseconds([&] { Volume copy(volume->dims(), volume->spacing_mm(), values, volume->metadata()); });
  const double histogram = Milliseconds(
      [&] { ValueHistogram::Of(ValuesView<float>(values), 0.0f, volume->min_value(), volume->max_value()); });
  VolumeKindJudgement kind;
  const double judge = Milliseconds([&] { kind = JudgeVolumeKind(*volume); });
  v1::Scene scene = MakePresetScene(DefaultPreset(kind.kind), *volume);
  scene.mutable_render()->set_width(1280);
  scene.mutable_render()->set_height(720);
  ApplyDefaults(scene);
  const TransferFunction tf = ResolveTransferFunction(scene.transfer_function(), *volume);
  const double frame = Milliseconds([&] { ResolveCamera(scene.camera(), scene.render(), *volume, tf); });
  const Vec3i d = volume->dims();
  return fmt::format("| {} | {}x{}x{} | {:.0f} | {:.0f} | {:.0f} | {:.3f} | {} | {:.1f} |\n", spec, d.x, d.y, d.z,
                     load, construct, histogram, judge, DefaultPreset(kind.kind), frame);
}

}  // namespace

int RunVolumeBench(const VolumeBenchOptions& options) {
  std::string table = fmt::format(
      "\n`{}` ({})\n\n| volume | voxels | load ms | Volume() ms | of which histogram ms | kind ms | default preset "
      "| framing ms |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n",
      options.command_line, DeviceDescription("cpu"));
  for (const std::string& spec : options.volumes) table += Row(spec);
  SceneOptions report;
  report.out = options.out;
  Report(report, table);
  return 0;
}

}  // namespace cinevol::bench

// `cinevol slice --scene S --axis axial|coronal|sagittal --position MM [--window W --level L | --preset NAME]
// [--slab MM --projection max|min|mean] [--nearest] [--no-labels] [--clip] --out F.png`: a reading slice of a
// scene's volume at its own pixel spacing (docs/reading.md), no server involved.
#include <fmt/format.h>

#include <chrono>
#include <map>
#include <optional>
#include <vector>

#include "commands.h"
#include "core/error.h"
#include "encode/image_codecs.h"
#include "offline_render.h"
#include "reading/slice.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"

namespace cinevol::cli {
namespace {

struct SliceOptions {
  std::string scene, out, axis = "axial", preset, projection = "max";
  std::optional<float> position_mm;  // default: the volume's middle along the axis
  std::optional<double> window, level;
  float slab_mm = 0;
  bool nearest = false, no_labels = false, clip = false;
};

const std::map<std::string, SliceAxis> kAxes = {
    {"axial", SliceAxis::kAxial}, {"coronal", SliceAxis::kCoronal}, {"sagittal", SliceAxis::kSagittal}};
const std::map<std::string, SlabProjection> kProjections = {
    {"max", SlabProjection::kMax}, {"min", SlabProjection::kMin}, {"mean", SlabProjection::kMean}};

// --window/--level, else --preset (CLI11 refuses both), else the volume's default; `name` says which.
VoiWindow ChooseWindow(const SliceOptions& o, const Volume& volume, std::string& name) {
  if (o.window.has_value() != o.level.has_value()) throw InputError("slice: --window and --level go together");
  if (o.window) {
    name = "given";
    return {*o.level, *o.window};
  }
  if (o.preset == "auto") {
    name = "auto";
    return AutoVoiWindow(volume.histogram());
  }
  if (!o.preset.empty()) {
    name = o.preset;
    return *FindWindowPreset(o.preset);
  }
  return DefaultWindow(volume, &name);
}

float ChoosePosition(const SliceOptions& o, const Volume& volume, SliceAxis axis) {
  const PositionRange range = SlicePositionRange(volume, axis);
  if (!o.position_mm) return 0.5f * (range.lo + range.hi);
  constexpr float kSlack = 1e-3f;  // mm: positions printed from the range itself
  if (*o.position_mm < range.lo - kSlack || *o.position_mm > range.hi + kSlack) {
    throw InputError(fmt::format("slice: --position {} mm is outside the volume's {} range [{:.3f}, {:.3f}] mm",
                                 *o.position_mm, o.axis, range.lo, range.hi));
  }
  return *o.position_mm;
}

// The line on stdout: what was written, where it lies and how it was windowed.
std::string Describe(const SliceOptions& o, const SliceSpec& spec, const SliceGeometry& g, const std::string& window,
                     double seconds) {
  const char lps_axis = spec.axis == SliceAxis::kAxial ? 'z' : (spec.axis == SliceAxis::kCoronal ? 'y' : 'x');
  std::string slab = spec.slab_mm > 0 ? fmt::format(", slab {:g} mm {}", spec.slab_mm, ToString(spec.projection)) : "";
  return fmt::format(
      "wrote {}: {} {}={:g} mm, {}x{} px, {:g}x{:g} mm, window {:g} level {:g} ({}){}, "
      "left {} right {} top {} bottom {}, {:.1f} ms",
      o.out, ToString(spec.axis), lps_axis, spec.position_mm, g.width, g.height, g.pixel_width_mm, g.pixel_height_mm,
      spec.window.width, spec.window.center, window, slab, g.letters.left, g.letters.right, g.letters.top,
      g.letters.bottom, seconds * 1e3);
}

SliceSpec SpecOf(const SliceOptions& o, const Volume& volume, std::string& window_name) {
  SliceSpec spec;
  spec.axis = kAxes.at(o.axis);
  spec.position_mm = ChoosePosition(o, volume, spec.axis);
  spec.window = ChooseWindow(o, volume, window_name);
  spec.nearest = o.nearest;
  spec.slab_mm = o.slab_mm;
  spec.projection = kProjections.at(o.projection);
  return spec;
}

void Run(const SliceOptions& o) {
  if (std::filesystem::path(o.out).extension() != ".png") throw InputError("slice: --out must be a .png file");
  const v1::Scene scene = LoadSceneFile(o.scene);
  const OfflineScene loaded = LoadOfflineScene(scene, {});
  const Volume& volume = *loaded.volume;
  std::string window_name;
  const SliceSpec spec = SpecOf(o, volume, window_name);
  const LabelSetup styles = ResolveLabels(scene.labels(), volume);
  const SliceLabels labels{o.no_labels ? nullptr : loaded.labels.get(), &styles};
  const ClipRegion clip = ResolveClipping(scene.clipping(), volume);
  const auto start = std::chrono::steady_clock::now();
  const SliceImage slice = RenderSlice(volume, labels, o.clip ? &clip : nullptr, spec);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  WriteFile(o.out, EncodePng(slice.image));
  fmt::print("{}\n", Describe(o, spec, slice.geometry, window_name, seconds));
}

}  // namespace

void AddSliceCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("slice", "Write a window/levelled slice of a scene's volume as PNG, no server");
  auto o = std::make_shared<SliceOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (JSON of cinevol.v1.Scene)")->required();
  cmd->add_option("--out", o->out, "Output image (.png)")->required();
  cmd->add_option("--axis", o->axis, "axial, coronal or sagittal")
      ->check(CLI::IsMember({"axial", "coronal", "sagittal"}));
  cmd->add_option("--position", o->position_mm,
                  "LPS mm along the axis: z axial, y coronal, x sagittal (default: middle)");
  auto* window =
      cmd->add_option("--window", o->window, "Window width (>= 1), with --level")->check(CLI::Range(1.0, 1e9));
  auto* level = cmd->add_option("--level", o->level, "Window centre, with --window");
  std::vector<std::string> presets{"auto"};
  for (const WindowPreset& p : WindowPresets()) presets.push_back(p.name);
  cmd->add_option("--preset", o->preset,
                  "brain, soft-tissue, lung, bone or auto (default: soft-tissue for HU, else auto)")
      ->check(CLI::IsMember(presets))
      ->excludes(window)
      ->excludes(level);
  cmd->add_option("--slab", o->slab_mm, "Slab thickness, mm (default 0: a thin slice)")->check(CLI::Range(0.0, 1e4));
  cmd->add_option("--projection", o->projection, "Through a slab: max, min or mean")
      ->check(CLI::IsMember({"max", "min", "mean"}));
  cmd->add_flag("--nearest", o->nearest, "Nearest-neighbour values instead of linear interpolation");
  cmd->add_flag("--no-labels", o->no_labels, "Leave out the segmentation's overlay");
  cmd->add_flag("--clip", o->clip, "Show the scene's crop box and clip planes (cut away: black)");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

// `cinevol slice (--scene S | --volume PATH) [--axis axial|coronal|sagittal --position MM | --axis oblique --point X,Y,Z
// --normal X,Y,Z [--row X,Y,Z]] [--window W --level L | --preset NAME] [--slab MM --projection max|min|mean]
// [--nearest] [--no-labels] [--clip] [--native-pixels] --out F.png`: a reading slice of a scene's volume
// (docs/reading.md), square pixels at the smaller in-plane spacing (--native-pixels: axis slices at the
// volume's own spacing, one pixel a voxel), oblique ones at its smallest; no server involved.
#include <fmt/format.h>

#include <array>
#include <cstdio>
#include <chrono>
#include <cmath>
#include <cstdlib>
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
  SceneSource source;
  std::string out, axis = "axial", preset, projection = "max";  // preset: the window's
  std::optional<float> position_mm;  // default: the volume's middle along the axis
  // --axis oblique: "X,Y,Z" in LPS. point: mm (default: the volume's centre); normal and row: directions
  // (row default: +L, or +P for a normal mostly along x).
  std::optional<std::string> point, normal, row;
  std::optional<double> window, level;
  float slab_mm = 0;
  bool nearest = false, no_labels = false, clip = false;
  bool native_pixels = false;  // axis slices: one pixel a voxel, not square where the voxels are not
};

const std::map<std::string, SliceAxis> kAxes = {{"axial", SliceAxis::kAxial},
                                                {"coronal", SliceAxis::kCoronal},
                                                {"sagittal", SliceAxis::kSagittal},
                                                {"oblique", SliceAxis::kOblique}};
const std::map<std::string, SlabProjection> kProjections = {
    {"max", SlabProjection::kMax}, {"min", SlabProjection::kMin}, {"mean", SlabProjection::kMean}};

// --window/--level, else --preset (CLI11 refuses both), else the volume's default; `name` says which.
VoiWindow ChooseWindow(const SliceOptions& o, const Volume& volume, std::string& name) {
  if (o.window.has_value() != o.level.has_value()) throw InputError("slice: --window and --level go together");
  if (o.window) {
    name = "given";
    return {*o.level, *o.window};
  }
  if (o.preset.empty()) return DefaultWindow(volume, &name);
  name = o.preset;
  return WindowNamed(o.preset, volume);
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

using Vec3d = std::array<double, 3>;

double Dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// "X,Y,Z": three finite numbers, or InputError naming the flag.
Vec3d ParseTriple(const std::string& text, const char* flag) {
  Vec3d v{};
  const char* at = text.c_str();
  for (int i = 0; i < 3; ++i) {
    char* end = nullptr;
    v[i] = std::strtod(at, &end);
    const bool separated = i < 2 ? *end == ',' : *end == '\0';
    if (end == at || !separated) {
      throw InputError(fmt::format("slice: {} '{}': give three numbers X,Y,Z (LPS)", flag, text));
    }
    if (!std::isfinite(v[i]) || std::abs(v[i]) > 1e6) {
      throw InputError(fmt::format("slice: {} '{}': each number must be finite, within +-1e6", flag, text));
    }
    at = end + 1;
  }
  return v;
}

// A direction flag as a unit vector; a zero one is refused.
Vec3d ParseDirection(const std::string& text, const char* flag) {
  Vec3d v = ParseTriple(text, flag);
  const double length = std::sqrt(Dot(v, v));
  if (!(length > 0)) throw InputError(fmt::format("slice: {} {}: a direction must not be zero", flag, text));
  for (double& c : v) c /= length;
  return v;
}

Vec3f ToVec3f(const Vec3d& v) { return {float(v[0]), float(v[1]), float(v[2])}; }

// The LPS position (mm) of voxel centre `index` (fractional indices allowed).
Vec3d VoxelCentre(const Volume& volume, const Vec3d& index) {
  const VolumeMetadata& m = volume.metadata();
  const Vec3f s = volume.spacing_mm();
  const Vec3d mm{index[0] * s.x, index[1] * s.y, index[2] * s.z};
  Vec3d p = m.origin_mm;
  for (int r = 0; r < 3; ++r) p[r] += Dot({m.direction[3 * r], m.direction[3 * r + 1], m.direction[3 * r + 2]}, mm);
  return p;
}

// Where a plane through `point` across `normal` (unit) meets the volume: the
// signed distances (mm) of its outermost voxel centres from the plane, least and most.
std::pair<double, double> CornerDistances(const Volume& volume, const Vec3d& point, const Vec3d& normal) {
  const Vec3i d = volume.dims();
  double lo = INFINITY, hi = -INFINITY;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3d index{corner & 1 ? d.x - 1.0 : 0.0, corner & 2 ? d.y - 1.0 : 0.0, corner & 4 ? d.z - 1.0 : 0.0};
    const Vec3d c = VoxelCentre(volume, index);
    const double distance = Dot({c[0] - point[0], c[1] - point[1], c[2] - point[2]}, normal);
    lo = std::min(lo, distance), hi = std::max(hi, distance);
  }
  return {lo, hi};
}

// The oblique flags' plane: --point (default the volume's centre) on the
// volume, --normal, --row (default +L, or +P for a normal mostly along x, as
// the axis slices have them) across the normal.
void ChooseObliquePlane(const SliceOptions& o, const Volume& volume, SliceSpec& spec) {
  if (o.position_mm) throw InputError("slice: --position is for axial, coronal and sagittal; oblique takes --point");
  if (!o.normal) throw InputError("slice: --axis oblique needs --normal X,Y,Z (and --point X,Y,Z, --row X,Y,Z)");
  const Vec3d normal = ParseDirection(*o.normal, "--normal");
  const Vec3i d = volume.dims();
  const Vec3d point = o.point ? ParseTriple(*o.point, "--point")
                              : VoxelCentre(volume, {0.5 * (d.x - 1), 0.5 * (d.y - 1), 0.5 * (d.z - 1)});
  const bool sagittal_like = std::abs(normal[0]) >= std::abs(normal[1]) && std::abs(normal[0]) >= std::abs(normal[2]);
  const Vec3d row = o.row ? ParseDirection(*o.row, "--row") : (sagittal_like ? Vec3d{0, 1, 0} : Vec3d{1, 0, 0});
  // As the library refuses it (reading/slice.cpp): less than 1e-3 of the row across the normal.
  const double along = Dot(row, normal);
  if (!(std::sqrt(std::max(0.0, 1 - along * along)) > 1e-3)) {
    throw InputError(fmt::format("slice: --row {} lies along --normal {}: the row must cross the normal",
                                 o.row.value_or(""), *o.normal));
  }
  const auto [lo, hi] = CornerDistances(volume, point, normal);
  constexpr double kSlack = 1e-3;  // mm
  if (lo > kSlack || hi < -kSlack) {
    throw InputError(
        fmt::format("slice: the plane through --point {:g},{:g},{:g} misses the volume: its voxels lie "
                    "{:.3f} to {:.3f} mm from it along --normal",
                    point[0], point[1], point[2], lo, hi));
  }
  spec.point_lps = ToVec3f(point);
  spec.normal_lps = ToVec3f(normal);
  spec.row_lps = ToVec3f(row);
}

// The line on stdout: what was written, where it lies and how it was windowed.
std::string Describe(const SliceOptions& o, const SliceSpec& spec, const SliceGeometry& g, const std::string& window,
                     double seconds) {
  std::string plane;
  if (spec.axis == SliceAxis::kOblique) {
    const Vec3f p = spec.point_lps, n = g.normal, r = g.row_direction;
    plane = fmt::format("oblique through {:g},{:g},{:g} mm, normal {:.4g},{:.4g},{:.4g}, row {:.4g},{:.4g},{:.4g}", p.x,
                        p.y, p.z, n.x, n.y, n.z, r.x, r.y, r.z);
  } else {
    const char lps_axis = spec.axis == SliceAxis::kAxial ? 'z' : (spec.axis == SliceAxis::kCoronal ? 'y' : 'x');
    plane = fmt::format("{} {}={:g} mm", ToString(spec.axis), lps_axis, spec.position_mm);
  }
  std::string slab = spec.slab_mm > 0 ? fmt::format(", slab {:g} mm {}", spec.slab_mm, ToString(spec.projection)) : "";
  return fmt::format(
      "wrote {}: {}, {}x{} px, {:g}x{:g} mm, window {:g} level {:g} ({}){}, "
      "left {} right {} top {} bottom {}, {:.1f} ms",
      o.out, plane, g.width, g.height, g.pixel_width_mm, g.pixel_height_mm, spec.window.width, spec.window.center,
      window, slab, g.letters.left, g.letters.right, g.letters.top, g.letters.bottom, seconds * 1e3);
}

SliceSpec SpecOf(const SliceOptions& o, const Volume& volume, std::string& window_name) {
  SliceSpec spec;
  spec.axis = kAxes.at(o.axis);
  if (spec.axis == SliceAxis::kOblique) {
    ChooseObliquePlane(o, volume, spec);
  } else {
    if (o.point || o.normal || o.row) throw InputError("slice: --point, --normal and --row are for --axis oblique");
    spec.position_mm = ChoosePosition(o, volume, spec.axis);
  }
  // Image viewers show every pixel square: anisotropic voxels are resampled unless asked not to be.
  if (spec.axis != SliceAxis::kOblique && !o.native_pixels) spec.pixel_mm = SquarePixelMm(volume, spec.axis);
  spec.window = ChooseWindow(o, volume, window_name);
  spec.nearest = o.nearest;
  spec.slab_mm = o.slab_mm;
  spec.projection = kProjections.at(o.projection);
  return spec;
}

void Run(const SliceOptions& o) {
  if (std::filesystem::path(o.out).extension() != ".png") throw InputError("slice: --out must be a .png file");
  const OfflineScene loaded = LoadOfflineScene(o.source);
  const v1::Scene& scene = loaded.scene;
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
  if (const std::string misfit = WindowMisfit(o.preset, volume); !misfit.empty()) {
    std::fprintf(stderr, "cinevol: %s\n", misfit.c_str());
  }
  fmt::print("{}\n", Describe(o, spec, slice.geometry, window_name, seconds));
}

}  // namespace

void AddSliceCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("slice", "Write a window/levelled slice of a scene's volume as PNG, no server");
  auto o = std::make_shared<SliceOptions>();
  AddSceneSource(cmd, o->source, SceneFlags::kWithoutPresetOrSize);  // --preset is the window's here
  cmd->add_option("--out", o->out, "Output image (.png)")->required();
  cmd->add_option("--axis", o->axis, "axial, coronal, sagittal or oblique")
      ->check(CLI::IsMember({"axial", "coronal", "sagittal", "oblique"}));
  cmd->add_option("--position", o->position_mm,
                  "LPS mm along the axis: z axial, y coronal, x sagittal (default: middle)")
      ->check(CLI::Range(-1e6, 1e6));
  cmd->add_option("--point", o->point, "Oblique: a point of the plane, X,Y,Z LPS mm (default: the volume's centre)");
  cmd->add_option("--normal", o->normal, "Oblique: the plane's normal, X,Y,Z (LPS)");
  cmd->add_option("--row", o->row,
                  "Oblique: the direction along the image's rows, X,Y,Z (LPS; default +L, or +P for a normal mostly "
                  "along x); the column is normal x row");
  auto* window =
      cmd->add_option("--window", o->window, "Window width (>= 1), with --level")->check(CLI::Range(1.0, 1e9));
  auto* level = cmd->add_option("--level", o->level, "Window centre, with --window");
  std::vector<std::string> presets{"auto", "stored"};
  for (const WindowPreset& p : WindowPresets()) presets.push_back(p.name);
  cmd->add_option("--preset", o->preset,
                  "brain, soft-tissue, lung, bone, auto or stored (the DICOM's own; default: stored where there "
                  "is one, else soft-tissue for HU, else auto)")
      ->check(CLI::IsMember(presets))
      ->excludes(window)
      ->excludes(level);
  cmd->add_option("--slab", o->slab_mm, "Slab thickness, mm (default 0: a thin slice)")->check(CLI::Range(0.0, 1e4));
  cmd->add_option("--projection", o->projection, "Through a slab: max, min or mean")
      ->check(CLI::IsMember({"max", "min", "mean"}));
  cmd->add_flag("--nearest", o->nearest, "Nearest-neighbour values instead of linear interpolation");
  cmd->add_flag("--native-pixels", o->native_pixels,
                "Axis slices: one pixel a voxel (not square where the voxels are not); default: square pixels at "
                "the smaller in-plane spacing");
  cmd->add_flag("--no-labels", o->no_labels, "Leave out the segmentation's overlay");
  cmd->add_flag("--clip", o->clip, "Show the scene's crop box and clip planes (cut away: black)");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

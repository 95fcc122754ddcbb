// RenderSlice: plan the plane's pixels, then one pass over them in the
// volume's index space (every step between pixels and slab samples is a
// fixed offset there).
#include "reading/slice.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/parallel_for.h"
#include "core/tone_map.h"
#include "scene/scene_frame.h"

namespace cinevol {
namespace {

// A plane through `point` with its image axes (unit, perpendicular).
struct PlaneAxes {
  Vec3f point, row, column;
};

// A direction that normalises: finite, not zero, its length not overflowing.
bool IsDirection(Vec3f v) {
  const float length = Length(v);
  return length > 0.0f && std::isfinite(length);
}

PlaneAxes ObliqueAxes(const SliceSpec& spec) {
  if (!IsDirection(spec.normal_lps) || !IsDirection(spec.row_lps) || !IsFinite(spec.point_lps) ||
      !(MaxComponent(Abs(spec.point_lps)) <= kMaxPlaneMm)) {
    throw InputError(
        fmt::format("slice: an oblique plane needs a point within {:g} mm of the origin and finite, "
                    "non-zero normal and row directions",
                    kMaxPlaneMm));
  }
  const Vec3f normal = Normalize(spec.normal_lps);
  const Vec3f row = spec.row_lps - normal * Dot(spec.row_lps, normal);
  if (!(Length(row) > 1e-3f * Length(spec.row_lps))) throw InputError("slice: the row direction is along the normal");
  const Vec3f unit_row = Normalize(row);
  return {spec.point_lps, unit_row, Cross(normal, unit_row)};
}

PlaneAxes AxesOf(const SliceSpec& spec) {
  const float p = spec.position_mm;
  switch (spec.axis) {
    case SliceAxis::kAxial:
      return {{0, 0, p}, {1, 0, 0}, {0, 1, 0}};
    case SliceAxis::kCoronal:
      return {{0, p, 0}, {1, 0, 0}, {0, 0, -1}};
    case SliceAxis::kSagittal:
      return {{p, 0, 0}, {0, 1, 0}, {0, 0, -1}};
    case SliceAxis::kOblique:
      break;
  }
  return ObliqueAxes(spec);
}

// The LPS positions of the volume's eight outermost voxel centres.
std::vector<Vec3f> CornerCentres(const Volume& volume) {
  const VolumePlacement placement = VolumePlacement::Of(volume);
  const Vec3f last = ToFloat(volume.dims()) - Vec3f{1, 1, 1};
  std::vector<Vec3f> corners;
  for (int i = 0; i < 8; ++i) {
    const Vec3f index{i & 1 ? last.x : 0.0f, i & 2 ? last.y : 0.0f, i & 4 ? last.z : 0.0f};
    corners.push_back(placement.DirectionToPatient(index * volume.spacing_mm()) + placement.origin);
  }
  return corners;
}

// The spacing of the index axis closest to `direction`: one pixel per voxel.
float SpacingAlong(const Volume& volume, Vec3f direction) {
  int best = 0;
  float best_cosine = -1;
  for (int a = 0; a < 3; ++a) {
    const float cosine = std::abs(Dot(IndexAxisDirection(volume.metadata().direction, a), direction));
    if (cosine > best_cosine) best = a, best_cosine = cosine;
  }
  return volume.spacing_mm()[best];
}

struct Span {
  float lo = std::numeric_limits<float>::infinity(), hi = -std::numeric_limits<float>::infinity();
};

Span ProjectCorners(const std::vector<Vec3f>& corners, Vec3f from, Vec3f direction) {
  Span span;
  for (Vec3f c : corners) {
    const float t = Dot(c - from, direction);
    span.lo = std::min(span.lo, t), span.hi = std::max(span.hi, t);
  }
  return span;
}

// Pixels covering `span` at `pixel_mm`, the outermost centres on its ends.
// The pixel size keeps it within kMaxSliceSide (FitToScreen).
int PixelsOver(Span span, float pixel_mm) {
  return int(std::min(std::round(double(span.hi - span.lo) / pixel_mm), double(kMaxSliceSide - 1))) + 1;
}

// How much larger pixels must be for both spans to fit kMaxSliceSide (1: they fit).
double FitToScreen(Span across, Span down, float pixel_width_mm, float pixel_height_mm) {
  const double longest =
      std::max(double(across.hi - across.lo) / pixel_width_mm, double(down.hi - down.lo) / pixel_height_mm);
  return std::max(1.0, longest / (kMaxSliceSide - 1));
}

// The slab's samples on each side of the plane, and the step between them:
// the volume's step along the normal, or further apart where the slice would
// otherwise take more than kMaxSliceSamples. A hair over half: a slab of
// exactly k steps keeps its outermost samples. No further than the volume's
// diagonal: samples beyond it are never inside.
void PlanSlab(const Volume& volume, float slab_mm, SliceGeometry& g) {
  g.slab_step_mm = SlabStep(volume, g.normal);
  const double reach = std::min(double(slab_mm) / 2, double(Length(volume.extent_mm())));
  const double wanted = std::floor(reach / g.slab_step_mm + 1e-4);
  const long long pixels = static_cast<long long>(g.width) * g.height;
  const double affordable = std::floor((double(kMaxSliceSamples) / double(pixels) - 1) / 2);
  g.slab_half = int(std::max(0.0, std::min(wanted, affordable)));
  if (wanted > affordable && g.slab_half > 0) g.slab_step_mm = float(reach / g.slab_half);
}

// A slice on the spec's own grid, its top-left pixel on the plane's point.
SliceGeometry PlanGrid(const Volume& volume, const SliceSpec& spec, const PlaneAxes& axes, SliceGeometry& g) {
  const SliceSpec::Grid& grid = *spec.grid;
  const auto size_ok = [](float mm) { return mm > 0.0f && mm <= 1e4f; };
  if (spec.axis != SliceAxis::kOblique || grid.width < 1 || grid.height < 1 || grid.width > kMaxSliceSide ||
      grid.height > kMaxSliceSide || !size_ok(grid.pixel_width_mm) || !size_ok(grid.pixel_height_mm)) {
    throw InputError(
        fmt::format("slice: a grid of {}x{} pixels of {:g}x{:g} mm: an oblique plane's, each side in "
                    "[1, {}], each pixel size in (0, 1e4] mm",
                    grid.width, grid.height, grid.pixel_width_mm, grid.pixel_height_mm, kMaxSliceSide));
  }
  g.width = grid.width, g.height = grid.height;
  g.pixel_width_mm = grid.pixel_width_mm, g.pixel_height_mm = grid.pixel_height_mm;
  PlanSlab(volume, spec.slab_mm, g);
  g.top_left_lps = axes.point;
  g.letters = EdgeLettersOf(g.row_direction, g.column_direction);
  return g;
}

// Voxel values in index space (voxel centres at integers), clamped to the
// grid at its edges as the renderers' lookups are.
template <class T>
struct VoxelGrid {
  const T* voxels;
  Vec3i dims;
  float offset;  // value = stored + offset

  float Stored(int x, int y, int z) const {
    x = std::clamp(x, 0, dims.x - 1), y = std::clamp(y, 0, dims.y - 1), z = std::clamp(z, 0, dims.z - 1);
    return float(voxels[(std::int64_t(z) * dims.y + y) * dims.x + x]);
  }
  // Within half a voxel of a voxel centre: inside the volume's box.
  bool Inside(Vec3f q) const {
    return q.x >= -0.5f && q.y >= -0.5f && q.z >= -0.5f && q.x <= float(dims.x) - 0.5f && q.y <= float(dims.y) - 0.5f &&
           q.z <= float(dims.z) - 0.5f;
  }
  // The index of the voxel nearest q, clamped to the grid: for values and labels alike.
  std::int64_t NearestIndex(Vec3f q) const {
    const int x = std::clamp(int(std::floor(q.x + 0.5f)), 0, dims.x - 1);
    const int y = std::clamp(int(std::floor(q.y + 0.5f)), 0, dims.y - 1);
    const int z = std::clamp(int(std::floor(q.z + 0.5f)), 0, dims.z - 1);
    return (std::int64_t(z) * dims.y + y) * dims.x + x;
  }
  float Nearest(Vec3f q) const { return float(voxels[NearestIndex(q)]) + offset; }
  float Linear(Vec3f q) const {
    const float fx = std::floor(q.x), fy = std::floor(q.y), fz = std::floor(q.z);
    const int x = int(fx), y = int(fy), z = int(fz);
    const float tx = q.x - fx, ty = q.y - fy, tz = q.z - fz;
    auto along_x = [&](int yy, int zz) {
      const float a = Stored(x, yy, zz);
      return a + tx * (Stored(x + 1, yy, zz) - a);
    };
    const float c00 = along_x(y, z), c10 = along_x(y + 1, z), c01 = along_x(y, z + 1), c11 = along_x(y + 1, z + 1);
    const float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0) + offset;
  }
};

// Where pixel (0, 0)'s plane sample is in index space, and the steps to the
// next column, the next row and the next slab sample.
struct IndexSteps {
  Vec3f first, column, row, slab;
  int slab_half = 0;  // samples on each side of the plane
};

// The first pixel's index coordinates within this of a whole number are
// taken as it: the float round trip through patient space leaves a plane on
// voxel centres a hair off them, and linear interpolation would blend in the
// neighbours by that hair. (The steps of an axis-aligned slice come out exact.)
constexpr float kOnGrid = 1e-4f;

Vec3f SnapToGrid(Vec3f q) {
  for (int a = 0; a < 3; ++a) {
    const float whole = std::round(q[a]);
    if (std::abs(q[a] - whole) < kOnGrid) q[a] = whole;
  }
  return q;
}

IndexSteps StepsOf(const Volume& volume, const SliceGeometry& g) {
  const VolumePlacement placement = VolumePlacement::Of(volume);
  const Vec3f spacing = volume.spacing_mm();
  auto index_of = [&](Vec3f lps) { return SnapToGrid((placement.PointToVolume(lps) - placement.shift) / spacing); };
  auto step_of = [&](Vec3f lps_step) { return placement.DirectionToVolume(lps_step) / spacing; };
  return {index_of(g.top_left_lps), step_of(g.row_direction * g.pixel_width_mm),
          step_of(g.column_direction * g.pixel_height_mm), step_of(g.normal * g.slab_step_mm), g.slab_half};
}

// The scene's half-spaces (world mm, ResolveClipping) in index space.
std::vector<Vec4f> ClipInIndexSpace(const ClipRegion* clip, const Volume& volume) {
  std::vector<Vec4f> half_spaces;
  if (!clip) return half_spaces;
  const Vec3f spacing = volume.spacing_mm(), shift = VolumePlacement::Of(volume).shift;
  // Dot(n, q * spacing + shift) + w = Dot(n * spacing, q) + Dot(n, shift) + w.
  for (int i = 0; i < clip->count; ++i) {
    const Vec3f n = Xyz(clip->half_spaces[i]);
    half_spaces.push_back(ToVec4(n * spacing, Dot(n, shift) + clip->half_spaces[i].w));
  }
  return half_spaces;
}

// What an overlay paints for a stored label value: an sRGB colour (0-255)
// and its opacity; 0 paints nothing.
struct LabelPaint {
  Vec3f rgb;
  float alpha = 0;
};

// Labels without a colour of their own take these (sRGB; no grey, which
// the image is).
constexpr float kPalette[][3] = {{31, 119, 180}, {255, 127, 14},  {44, 160, 44},  {214, 39, 40}, {148, 103, 189},
                                 {140, 86, 75},  {227, 119, 194}, {188, 189, 34}, {23, 190, 207}};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

float Clamp01(float v) { return std::clamp(v, 0.0f, 1.0f); }

LabelPaint PaintOf(int label, const LabelStyle& style, float opacity) {
  if (label == 0 || style.hidden()) return {};
  const float* fallback = kPalette[(label - 1) % kPaletteSize];
  Vec3f rgb{fallback[0], fallback[1], fallback[2]};
  // A style's colour as 8-bit sRGB, as a colour picker shows it.
  for (int c = 0; c < 3 && style.has_color; ++c) rgb[c] = std::round(255.0f * LinearToSrgb(Clamp01(style.color[c])));
  return {rgb, std::clamp(opacity * style.opacity_scale, 0.0f, 1.0f)};
}

std::vector<LabelPaint> LabelPaints(const SliceLabels& labels, float opacity) {
  std::vector<LabelPaint> paints;
  if (!labels.volume) return paints;
  const LabelSetup shown_all{};
  const LabelSetup& setup = labels.setup ? *labels.setup : shown_all;
  for (int value = 0; value < labels.volume->value_count(); ++value) {
    const int label = labels.volume->LabelOf(value);  // derived values (shell, table) are label 0
    paints.push_back(PaintOf(label, setup.StyleOf(label), opacity));
  }
  return paints;
}

// One slice's pass over its pixels.
template <class T>
struct SlicePass {
  VoxelGrid<T> grid;
  IndexSteps steps;
  std::vector<Vec4f> clip;                // index space; empty keeps everything
  const std::uint16_t* labels = nullptr;  // on the grid; null: no overlay
  std::vector<LabelPaint> paints;         // by stored label value
  VoiWindow window;
  bool nearest = false;
  SlabProjection projection = SlabProjection::kMax;

  bool Keeps(Vec3f q) const {
    if (!grid.Inside(q)) return false;
    for (const Vec4f& h : clip) {
      if (Dot(Xyz(h), q) + h.w < 0.0f) return false;
    }
    return true;
  }

  // The slab's projection through plane sample q; false where no sample is kept.
  bool Project(Vec3f q, float& value) const {
    float acc = projection == SlabProjection::kMin   ? std::numeric_limits<float>::infinity()
                : projection == SlabProjection::kMax ? -std::numeric_limits<float>::infinity()
                                                     : 0.0f;
    int kept = 0;
    for (int j = -steps.slab_half; j <= steps.slab_half; ++j) {
      const Vec3f s = q + steps.slab * float(j);
      if (!Keeps(s)) continue;
      const float v = nearest ? grid.Nearest(s) : grid.Linear(s);
      acc = projection == SlabProjection::kMin   ? std::min(acc, v)
            : projection == SlabProjection::kMax ? std::max(acc, v)
                                                 : acc + v;
      ++kept;
    }
    value = projection == SlabProjection::kMean ? acc / float(std::max(kept, 1)) : acc;
    return kept > 0;
  }

  // The label overlay at plane sample q (nearest voxel), or nothing.
  LabelPaint PaintAt(Vec3f q) const {
    if (!labels || !Keeps(q)) return {};
    const std::uint16_t value = labels[grid.NearestIndex(q)];
    return value < paints.size() ? paints[value] : LabelPaint{};
  }

  void Pixel(int column, int row, std::uint8_t* rgb) const {
    const Vec3f q = steps.first + steps.column * float(column) + steps.row * float(row);
    float value = 0;
    if (!Project(q, value)) {
      rgb[0] = rgb[1] = rgb[2] = 0;
      return;
    }
    const float grey = ApplyVoiLinear(value, window);
    const LabelPaint paint = PaintAt(q);
    for (int c = 0; c < 3; ++c) rgb[c] = std::uint8_t(grey + (paint.rgb[c] - grey) * paint.alpha + 0.5f);
  }

  void Run(ImageRgb8& image, const std::atomic<bool>* cancel, int threads) const {
    ParallelFor(
        image.height,
        [&](std::int64_t row) {
          if (cancel && cancel->load(std::memory_order_relaxed)) return;
          std::uint8_t* line = image.bytes.data() + std::size_t(row) * image.width * 3;
          for (int column = 0; column < image.width; ++column) Pixel(column, int(row), line + 3 * column);
        },
        threads);
  }
};

template <class T>
void RunPass(const Volume& volume, const T* voxels, float offset, const SliceLabels& labels, const ClipRegion* clip,
             const SliceSpec& spec, const std::atomic<bool>* cancel, int threads, SliceImage& out) {
  SlicePass<T> pass{{voxels, volume.dims(), offset},
                    StepsOf(volume, out.geometry),
                    ClipInIndexSpace(clip, volume),
                    labels.volume ? labels.volume->labels.data() : nullptr,
                    LabelPaints(labels, spec.label_opacity),
                    spec.window,
                    spec.nearest,
                    spec.projection};
  pass.Run(out.image, cancel, threads);
}

// The second volume over the slice's pixels: each pixel's centre on the
// plane sampled on its own grid (linear), through the colour map where above
// the window's bottom.
template <class T>
void OverlayFusion(const SliceSpec::Fusion& fusion, const T* voxels, float offset, const SliceGeometry& g,
                   const std::atomic<bool>* cancel, int threads, ImageRgb8& image) {
  const Volume& volume = *fusion.volume;
  const VoxelGrid<T> grid{voxels, volume.dims(), offset};
  const VolumePlacement placement = VolumePlacement::Of(volume);
  const Vec3f spacing = volume.spacing_mm();
  auto index_of = [&](Vec3f lps) { return (placement.PointToVolume(lps) - placement.shift) / spacing; };
  const Vec3f first = index_of(g.PixelToPatient(0, 0));
  const Vec3f column = index_of(g.PixelToPatient(1, 0)) - first, row = index_of(g.PixelToPatient(0, 1)) - first;
  ParallelFor(
      image.height,
      [&](std::int64_t y) {
        if (cancel && cancel->load(std::memory_order_relaxed)) return;
        std::uint8_t* line = image.bytes.data() + std::size_t(y) * image.width * 3;
        for (int x = 0; x < image.width; ++x) {
          const Vec3f q = first + column * float(x) + row * float(y);
          if (!grid.Inside(q)) continue;
          const float t = (grid.Linear(q) * fusion.value_factor - fusion.lowest) / fusion.width;
          if (!(t > 0.0f)) continue;
          const Vec3f paint = ColorMapAt(fusion.color_map, std::min(t, 1.0f));
          for (int c = 0; c < 3; ++c) {
            std::uint8_t& v = line[3 * x + c];
            v = std::uint8_t(float(v) + (paint[c] - float(v)) * fusion.opacity + 0.5f);
          }
        }
      },
      threads);
}

void CheckRenderable(const Volume& volume, const SliceLabels& labels, const SliceSpec& spec) {
  if (!(spec.window.width >= 1.0 && std::isfinite(spec.window.width)) || !std::isfinite(spec.window.center)) {
    throw InputError(fmt::format("slice: window width {} and level {}: VOI LINEAR needs a finite width >= 1",
                                 spec.window.width, spec.window.center));
  }
  if (!(spec.label_opacity >= 0.0f && spec.label_opacity <= 1.0f))
    throw InputError("slice: label opacity outside [0, 1]");
  if (labels.volume &&
      !(labels.volume->dims == volume.dims() && labels.volume->labels.size() == volume.voxel_count())) {
    throw InputError("slice: the labels are not on the volume's grid");
  }
  const SliceSpec::Fusion& f = spec.fusion;
  if (f.volume && !(f.width > 0.0f && std::isfinite(f.width) && std::isfinite(f.lowest) &&
                    std::isfinite(f.value_factor) && f.opacity >= 0.0f && f.opacity <= 1.0f)) {
    throw InputError("slice: the second volume's window, factor or opacity is out of range");
  }
}

}  // namespace

const char* ToString(SliceAxis axis) {
  switch (axis) {
    case SliceAxis::kAxial:
      return "axial";
    case SliceAxis::kCoronal:
      return "coronal";
    case SliceAxis::kSagittal:
      return "sagittal";
    case SliceAxis::kOblique:
      break;
  }
  return "oblique";
}

Vec3f ColorMapAt(SliceColorMap map, float t) {
  t = std::clamp(t, 0.0f, 1.0f);
  switch (map) {
    case SliceColorMap::kGray:
      return Vec3f{1, 1, 1} * (255.0f * t);
    case SliceColorMap::kRainbow: {       // blue, cyan, green, yellow, red: hue from 240 to 0 degrees
      const float h = 4.0f * (1.0f - t);  // sextants 0 (red) to 4 (blue)
      const float f = h - std::floor(h);
      const int k = std::min(int(h), 3);
      const Vec3f stops[5] = {{1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}};
      return (stops[k] + (stops[k + 1] - stops[k]) * (h >= 4.0f ? 1.0f : f)) * 255.0f;
    }
    case SliceColorMap::kHot:
      break;
  }
  // Black, red, yellow, white: red rises over the first third, green the second, blue the last.
  return Vec3f{std::clamp(3 * t, 0.0f, 1.0f), std::clamp(3 * t - 1, 0.0f, 1.0f), std::clamp(3 * t - 2, 0.0f, 1.0f)} *
         255.0f;
}

const char* ToString(SlabProjection projection) {
  return projection == SlabProjection::kMax ? "max" : (projection == SlabProjection::kMin ? "min" : "mean");
}

SliceGeometry PlanSlice(const Volume& volume, const SliceSpec& spec) {
  if (!(std::abs(spec.position_mm) <= kMaxPlaneMm)) {
    throw InputError(fmt::format("slice: the position is outside [-{:g}, {:g}] mm", kMaxPlaneMm, kMaxPlaneMm));
  }
  const PlaneAxes axes = AxesOf(spec);
  if (!(spec.pixel_mm >= 0.0f && spec.pixel_mm <= 1e4f)) throw InputError("slice: pixel size outside [0, 1e4] mm");
  if (!(spec.slab_mm >= 0.0f && spec.slab_mm <= 1e4f)) throw InputError("slice: slab thickness outside [0, 1e4] mm");
  SliceGeometry g;
  g.row_direction = axes.row;
  g.column_direction = axes.column;
  g.normal = Cross(axes.row, axes.column);
  const bool oblique = spec.axis == SliceAxis::kOblique;
  const float square_mm = spec.pixel_mm > 0.0f ? spec.pixel_mm : MinComponent(volume.spacing_mm());
  const bool square = oblique || spec.pixel_mm > 0.0f;
  g.pixel_width_mm = square ? square_mm : SpacingAlong(volume, axes.row);
  g.pixel_height_mm = square ? square_mm : SpacingAlong(volume, axes.column);
  if (spec.grid) return PlanGrid(volume, spec, axes, g);
  const std::vector<Vec3f> corners = CornerCentres(volume);
  const Span across = ProjectCorners(corners, axes.point, axes.row);
  const Span down = ProjectCorners(corners, axes.point, axes.column);
  const double enlarge = FitToScreen(across, down, g.pixel_width_mm, g.pixel_height_mm);
  g.pixel_width_mm = float(g.pixel_width_mm * enlarge);
  g.pixel_height_mm = float(g.pixel_height_mm * enlarge);
  g.width = PixelsOver(across, g.pixel_width_mm);
  g.height = PixelsOver(down, g.pixel_height_mm);
  PlanSlab(volume, spec.slab_mm, g);
  g.top_left_lps = axes.point + axes.row * across.lo + axes.column * down.lo;
  g.letters = EdgeLettersOf(g.row_direction, g.column_direction);
  return g;
}

PositionRange SlicePositionRange(const Volume& volume, SliceAxis axis) {
  const int lps_axis = axis == SliceAxis::kAxial ? 2 : (axis == SliceAxis::kCoronal ? 1 : 0);
  PositionRange range{std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()};
  for (Vec3f c : CornerCentres(volume)) {
    range.lo = std::min(range.lo, c[lps_axis]), range.hi = std::max(range.hi, c[lps_axis]);
  }
  return range;
}

float SquarePixelMm(const Volume& volume, SliceAxis axis) {
  SliceSpec spec;
  spec.axis = axis;
  const PlaneAxes axes = AxesOf(spec);
  return std::min(SpacingAlong(volume, axes.row), SpacingAlong(volume, axes.column));
}

float SlabStep(const Volume& volume, Vec3f normal) {
  const Vec3f voxels_per_mm = VolumePlacement::Of(volume).DirectionToVolume(Normalize(normal)) / volume.spacing_mm();
  return 1.0f / Length(voxels_per_mm);
}

SliceImage RenderSlice(const Volume& volume, const SliceLabels& labels, const ClipRegion* clip, const SliceSpec& spec,
                       const std::atomic<bool>* cancel, int threads) {
  CheckRenderable(volume, labels, spec);
  SliceImage out;
  out.geometry = PlanSlice(volume, spec);
  out.image.width = out.geometry.width;
  out.image.height = out.geometry.height;
  out.image.bytes.assign(std::size_t(out.image.width) * out.image.height * 3, 0);
  if (volume.storage() == VoxelStorage::kUInt16) {
    RunPass(volume, volume.u16().data(), volume.stored_offset(), labels, clip, spec, cancel, threads, out);
  } else {
    RunPass(volume, volume.f32().data(), 0.0f, labels, clip, spec, cancel, threads, out);
  }
  if (const Volume* fused = spec.fusion.volume) {
    if (fused->storage() == VoxelStorage::kUInt16) {
      OverlayFusion(spec.fusion, fused->u16().data(), fused->stored_offset(), out.geometry, cancel, threads, out.image);
    } else {
      OverlayFusion(spec.fusion, fused->f32().data(), 0.0f, out.geometry, cancel, threads, out.image);
    }
  }
  if (cancel && *cancel) throw Cancelled("the slice was cancelled");
  return out;
}

}  // namespace cinevol

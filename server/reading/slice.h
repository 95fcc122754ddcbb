// Reading slices rendered on the CPU: axial, coronal, sagittal or oblique
// planes of a volume through a window/level to 8-bit grey, with slabs
// (maximum, minimum or mean along the normal), the label overlay and the
// scene's clipping. Deterministic and final in one pass: the same inputs
// give the same bytes.
//
// Conventions (radiological; docs/reading.md): image x runs along the row
// direction, image y down the column direction, the normal is row x column.
//   axial:    row +L, column +P  (R|L at the left|right edges, A top, P bottom)
//   coronal:  row +L, column +I  (R|L, S top, I bottom)
//   sagittal: row +P, column +I  (A|P, S top, I bottom)
#pragma once

#include <atomic>
#include <optional>
#include <string>

#include "core/clip_region.h"
#include "core/image.h"
#include "core/labels.h"
#include "core/vec.h"
#include "core/volume.h"
#include "reading/orientation.h"
#include "reading/window_level.h"

namespace cinevol {

enum class SliceAxis { kAxial, kCoronal, kSagittal, kOblique };
enum class SlabProjection { kMax, kMin, kMean };
// How a second volume's values colour a slice (Scene.fusion's overlay).
enum class SliceColorMap { kHot, kRainbow, kGray };
// The colour at `t` in [0, 1] along the map, each channel in [0, 255].
Vec3f ColorMapAt(SliceColorMap map, float t);

const char* ToString(SliceAxis axis);             // "axial", "coronal", "sagittal", "oblique"
const char* ToString(SlabProjection projection);  // "max", "min", "mean"

struct SliceSpec {
  SliceAxis axis = SliceAxis::kAxial;
  // Axis-aligned slices: the plane's LPS coordinate, mm: z (axial), y (coronal), x (sagittal).
  float position_mm = 0;
  // kOblique: a point of the plane, its normal and the direction along an
  // image row (LPS; made perpendicular to the normal). The column direction
  // is normal x row.
  Vec3f point_lps;
  Vec3f normal_lps{0, 0, 1};
  Vec3f row_lps{1, 0, 0};
  // Square pixels of this many mm, [0, 1e4]. 0: an oblique slice's are square
  // at the volume's smallest spacing, an axis-aligned slice's take the
  // volume's own spacing along each image axis (one pixel per voxel, not
  // square where the voxels are not: SquarePixelMm squares them). Either
  // grows where the image would be larger than kMaxSliceSide.
  float pixel_mm = 0;
  VoiWindow window;
  bool nearest = false;  // nearest-neighbour values instead of linear (labels are always nearest)
  // Thickness along the normal, mm, centred on the plane; [0, 1e4]. 0: a
  // thin slice. Samples lie every volume spacing along the normal (SlabStep)
  // from -slab/2 to +slab/2, the plane's one included; further apart where
  // the slice would take more than kMaxSliceSamples.
  float slab_mm = 0;
  SlabProjection projection = SlabProjection::kMax;
  // [0, 1]: a label's overlay opacity at its style's opacity_scale 1 (scaled by it, capped at 1).
  float label_opacity = 0.5f;
  // A grid of its own instead of the volume's projection onto the plane (a
  // DICOM frame's: Columns x Rows at its Pixel Spacing): oblique only,
  // `point_lps` its top-left pixel's centre; each side in [1, kMaxSliceSide],
  // each pixel size in (0, 1e4] mm. `pixel_mm` is not used.
  struct Grid {
    int width = 0, height = 0;
    float pixel_width_mm = 0, pixel_height_mm = 0;  // between columns, between rows
  };
  std::optional<Grid> grid;
  // A second volume drawn over the slice (Scene.fusion's overlay).
  struct Fusion {
    const Volume* volume = nullptr;  // null: none; sampled at the plane, on its own grid, by patient coordinates
    float value_factor = 1;          // its values are shown times this (a PET's SUVbw factor)
    float lowest = 0, width = 1;     // the shown values the colour map spans: [lowest, lowest + width], width > 0
    SliceColorMap color_map = SliceColorMap::kHot;
    float opacity = 0.5f;  // [0, 1], where a value is above `lowest`; below it nothing is drawn
  };
  Fusion fusion;
};

// Where a slice's pixels lie in the patient.
struct SliceGeometry {
  int width = 0, height = 0;
  Vec3f top_left_lps;         // LPS mm of the centre of pixel (0, 0), the top-left one
  Vec3f row_direction;        // LPS unit vector: to the next pixel of a row (image +x)
  Vec3f column_direction;     // LPS unit vector: to the next row (image +y)
  Vec3f normal;               // row x column
  float pixel_width_mm = 1;   // between columns
  float pixel_height_mm = 1;  // between rows
  int slab_half = 0;          // slab samples on each side of the plane
  float slab_step_mm = 0;     // between slab samples along the normal
  EdgeLetters letters;        // at the image's edges

  // LPS mm of image point (column, row): pixel centres at integers, (0, 0)
  // the top-left pixel's; a pixel's own position exactly.
  Vec3f PixelToPatient(float column, float row) const {
    return top_left_lps + row_direction * (column * pixel_width_mm) + column_direction * (row * pixel_height_mm);
  }
};

// A segmentation to overlay: its labels on the volume's grid (io/
// label_volume.h fits them), and how they show (Scene.labels resolved:
// colour, visible, opacity_scale). No volume: no overlay. No setup: every
// label shows in the default palette's colours. Label 0 and the derived
// values (shell, table) are never drawn.
struct SliceLabels {
  const LabelVolume* volume = nullptr;
  const LabelSetup* setup = nullptr;
};

struct SliceImage {
  ImageRgb8 image;
  SliceGeometry geometry;
};

// A slice is bounded by what a screen shows, not by millimetres: its longer
// side has at most kMaxSliceSide pixels (larger pixels where the plane would
// need more), and pixels times slab samples stay within kMaxSliceSamples
// (slab samples further apart where a thick slab would need more). So no
// spacing or slab, however hostile, makes a slice that holds a worker for long.
inline constexpr int kMaxSliceSide = 4096;
inline constexpr long long kMaxSliceSamples = 1LL << 27;
// A plane's position or point, mm from the patient's origin: far beyond any
// volume (8192 voxels of 10^4 mm), near enough that float arithmetic stays finite.
inline constexpr float kMaxPlaneMm = 1e9f;

// The plane, its pixels and slab samples without rendering them: the image
// covers the volume's projection onto the plane (voxel centres, the
// outermost ones on the edge pixels), within the bounds above, or the
// spec's own grid. Throws
// InputError for a zero normal or row, a row along the normal, or a pixel
// size or slab outside their ranges.
SliceGeometry PlanSlice(const Volume& volume, const SliceSpec& spec);

// The LPS coordinates (mm) of the outermost voxel centres along an
// axis-aligned slice's axis: where position_mm meets the volume.
struct PositionRange {
  float lo = 0, hi = 0;
};
PositionRange SlicePositionRange(const Volume& volume, SliceAxis axis);

// The pixel size that squares an axis-aligned slice's pixels without losing
// detail: the smaller of the volume's spacings along its two image axes
// (what image viewers, which show every pixel square, need).
float SquarePixelMm(const Volume& volume, SliceAxis axis);

// The distance between slab samples along `normal` (LPS): one voxel's
// reach along it, the axis's spacing for a normal along an index axis.
float SlabStep(const Volume& volume, Vec3f normal);

// Renders `spec`'s slice. Pixels with no sample inside the volume (and
// inside `clip`, where one is given) are black; `clip` is the scene's
// resolved crop box and clip planes (scene/scene_builder.h ResolveClipping,
// world mm); null ignores them. Throws InputError for a window narrower
// than 1, a negative slab or labels on another grid. Once `cancel` is raised
// (a caller gone, a deadline passed), the rows not yet begun are skipped and
// Cancelled thrown. `threads`: at most this many take part (0: every one of
// the compute pool; a server gives each slice its share).
SliceImage RenderSlice(const Volume& volume, const SliceLabels& labels, const ClipRegion* clip, const SliceSpec& spec,
                       const std::atomic<bool>* cancel = nullptr, int threads = 0);

}  // namespace cinevol

// SliceOf and PickOn: see reading_calls.h.
#include "runtime/reading_calls.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "encode/image_codecs.h"
#include "reading/pick.h"
#include "reading/slice.h"
#include "scene/scene_builder.h"
#include "scene/scene_frame.h"

namespace cinevol::service {
namespace {

Vec3f Finite(const v1::Vec3& v, const char* field) {
  if (!(std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()))) {
    throw InputError(fmt::format("{}: not finite numbers", field));
  }
  return {v.x(), v.y(), v.z()};
}

void ToProto(Vec3f v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

SliceAxis AxisOf(v1::SliceAxis axis) {
  switch (axis) {
    case v1::CORONAL:
      return SliceAxis::kCoronal;
    case v1::SAGITTAL:
      return SliceAxis::kSagittal;
    case v1::OBLIQUE:
      return SliceAxis::kOblique;
    case v1::AXIAL:
    case v1::SLICE_AXIS_UNSPECIFIED:
      return SliceAxis::kAxial;
    default:
      throw InputError(fmt::format("axis: unknown value {}", int(axis)));
  }
}

SlabProjection ProjectionOf(v1::SlabProjection projection) {
  switch (projection) {
    case v1::MINIMUM:
      return SlabProjection::kMin;
    case v1::MEAN:
      return SlabProjection::kMean;
    case v1::MAXIMUM:
    case v1::SLAB_PROJECTION_UNSPECIFIED:
      return SlabProjection::kMax;
    default:
      throw InputError(fmt::format("projection: unknown value {}", int(projection)));
  }
}

// The request's window: both numbers given, else a named preset (nothing:
// the volume's default, reading/window_level.h).
VoiWindow WindowOf(const v1::SliceRequest& request, const Volume& volume) {
  if (request.has_window() != request.has_level()) throw InputError("window, level: give both or neither");
  if (request.has_window()) {
    if (!(request.window() >= 1) || !std::isfinite(request.level())) {
      throw InputError(fmt::format("window: {} with level {}: the width must be at least 1 and both finite",
                                   request.window(), request.level()));
    }
    return {request.level(), request.window()};
  }
  try {
    return WindowNamed(request.window_preset(), volume);
  } catch (const InputError& e) {
    throw InputError(fmt::format("window_preset: {}", e.what()));
  }
}

}  // namespace

SliceSpec SliceSpecOf(const v1::SliceRequest& request, const Volume& volume) {
  SliceSpec spec;
  spec.axis = AxisOf(request.axis());
  if (!std::isfinite(request.position_mm())) throw InputError("position_mm: not a finite number");
  spec.position_mm = float(request.position_mm());
  if (spec.axis == SliceAxis::kOblique) {
    spec.point_lps = Finite(request.point(), "point");
    spec.normal_lps = Finite(request.normal(), "normal");
    spec.row_lps = Finite(request.row(), "row");
  }
  spec.window = WindowOf(request, volume);
  spec.nearest = request.nearest();
  // A slab past the volume's diagonal adds nothing but samples: bounded so, a hostile one holds no worker long.
  const float diagonal = Length(volume.extent_mm());
  if (!(request.slab_mm() >= 0 && request.slab_mm() <= diagonal)) {
    throw InputError(
        fmt::format("slab_mm: {} is outside [0, {:.0f}] (the volume's diagonal)", request.slab_mm(), diagonal));
  }
  spec.slab_mm = request.slab_mm();
  spec.projection = ProjectionOf(request.projection());
  if (!(request.pixel_mm() >= 0 && request.pixel_mm() <= 1e4f)) {
    throw InputError(fmt::format("pixel_mm: {} is outside [0, 1e4]", request.pixel_mm()));
  }
  spec.pixel_mm = request.pixel_mm();
  return spec;
}

namespace {

// A rendered slice as the API answers it: PNG, where its pixels lie, what window it went through.
v1::SliceImage AnswerOf(const SliceImage& slice, const SliceSpec& spec, std::string notice) {
  v1::SliceImage out;
  const std::vector<std::uint8_t> png = EncodePng(slice.image);
  out.set_png(std::string(png.begin(), png.end()));
  const SliceGeometry& g = slice.geometry;
  out.set_width(std::uint32_t(g.width));
  out.set_height(std::uint32_t(g.height));
  ToProto(g.top_left_lps, out.mutable_origin_mm());
  ToProto(g.row_direction, out.mutable_row_direction());
  ToProto(g.column_direction, out.mutable_column_direction());
  out.set_row_spacing_mm(g.pixel_width_mm);
  out.set_column_spacing_mm(g.pixel_height_mm);
  for (const std::string* letter : {&g.letters.left, &g.letters.right, &g.letters.top, &g.letters.bottom}) {
    out.add_edge_letters(*letter);
  }
  out.set_slab_samples(std::uint32_t(2 * g.slab_half + 1));
  out.set_slab_step_mm(g.slab_step_mm);
  out.set_notice(std::move(notice));
  out.set_window(float(spec.window.width));
  out.set_level(float(spec.window.center));
  return out;
}

Vec3f ToVec(const pacs::Triple& t) { return {float(t[0]), float(t[1]), float(t[2])}; }

// The frame's own grid, or its field of view (pixel edges, not centres) fitted within the viewport in square
// pixels, centred where it was; the spec's point moves to the grid's top-left pixel centre.
void PlaceGrid(const pacs::FramePlane& plane, const v1::Viewport* viewport, SliceSpec& spec) {
  SliceSpec::Grid grid{plane.columns, plane.rows, float(plane.column_spacing_mm), float(plane.row_spacing_mm)};
  if (viewport) {
    if (viewport->width() < 1 || viewport->height() < 1 || viewport->width() > std::uint32_t(kMaxSliceSide) ||
        viewport->height() > std::uint32_t(kMaxSliceSide)) {
      throw InputError(fmt::format("viewport: {}x{} is outside [1, {}] each way", viewport->width(), viewport->height(),
                                   kMaxSliceSide));
    }
    const double wide = plane.columns * plane.column_spacing_mm, tall = plane.rows * plane.row_spacing_mm;
    const double pixel = std::max(wide / viewport->width(), tall / viewport->height());
    grid = {int(std::clamp(std::lround(wide / pixel), 1L, long(viewport->width()))),
            int(std::clamp(std::lround(tall / pixel), 1L, long(viewport->height()))), float(pixel), float(pixel)};
  }
  if (grid.width > kMaxSliceSide || grid.height > kMaxSliceSide) {
    throw InputError(fmt::format("frame: {} x {} pixels; at most {} a side are rendered, give a viewport", grid.width,
                                 grid.height, kMaxSliceSide));
  }
  // The field's top-left corner, then half a pixel of the new grid in from it.
  const Vec3f row = ToVec(plane.row), column = ToVec(plane.column);
  const Vec3f corner =
      ToVec(plane.position) - row * float(plane.column_spacing_mm / 2) - column * float(plane.row_spacing_mm / 2);
  spec.point_lps = corner + row * (grid.pixel_width_mm / 2) + column * (grid.pixel_height_mm / 2);
  spec.grid = grid;
}

// How slices draw the scene's second volume: its overlay's colour map,
// window (unset: the volume's range) and opacity, in its shown values.
SliceSpec::Fusion OverlayOf(const v1::Fusion& fusion, const Volume& fused) {
  SliceSpec::Fusion overlay;
  const v1::FusionOverlay& o = fusion.overlay();
  if (o.opacity() <= 0) return overlay;  // none drawn
  overlay.volume = &fused;
  overlay.value_factor = fusion.suv() ? float(fused.metadata().suv_factor) : 1.0f;
  overlay.opacity = o.opacity();
  overlay.color_map = o.color_map() == v1::RAINBOW ? SliceColorMap::kRainbow
                      : o.color_map() == v1::GRAY  ? SliceColorMap::kGray
                                                   : SliceColorMap::kHot;
  if (o.has_window()) {
    overlay.lowest = o.level() - o.window() / 2;
    overlay.width = o.window();
  } else {
    overlay.lowest = fused.min_value() * overlay.value_factor;
    overlay.width = std::max((fused.max_value() - fused.min_value()) * overlay.value_factor, 1e-30f);
  }
  return overlay;
}

}  // namespace

v1::SliceImage SliceOf(const v1::SliceRequest& request, const v1::Scene& scene, const VolumeLease& lease,
                       const VolumeLease* fused, const std::atomic<bool>* cancel, int threads) {
  const Volume& volume = *lease.phase(int(scene.time().phase()));
  SliceSpec spec = SliceSpecOf(request, volume);
  if (fused && scene.has_fusion()) spec.fusion = OverlayOf(scene.fusion(), *fused->volume());
  const LabelSetup styles = ResolveLabels(scene.labels(), volume);
  const SliceLabels labels{request.hide_labels() ? nullptr : lease.labels().get(), &styles};
  const ClipRegion clip = ResolveClipping(scene.clipping(), volume);
  const SliceImage slice =
      RenderSlice(volume, labels, request.apply_clipping() ? &clip : nullptr, spec, cancel, threads);
  return AnswerOf(slice, spec, WindowMisfit(request.window_preset(), volume));
}

v1::SliceImage FrameOf(const v1::RenderFrameRequest& request, const pacs::FramePlane& plane, const Volume& volume,
                       const std::atomic<bool>* cancel, int threads) {
  v1::SliceRequest slice;  // the frame's plane as an oblique slice through its window
  slice.set_axis(v1::OBLIQUE);
  const Vec3f row = ToVec(plane.row), column = ToVec(plane.column), normal = Cross(row, column);
  ToProto(ToVec(plane.position), slice.mutable_point());
  ToProto(normal, slice.mutable_normal());
  ToProto(row, slice.mutable_row());
  if (request.has_window()) slice.set_window(request.window());
  if (request.has_level()) slice.set_level(request.level());
  SliceSpec spec = SliceSpecOf(slice, volume);
  PlaceGrid(plane, request.has_viewport() ? &request.viewport() : nullptr, spec);
  const SliceImage image = RenderSlice(volume, SliceLabels{}, nullptr, spec, cancel, threads);
  return AnswerOf(image, spec, WindowMisfit("", volume));
}

v1::PickResult PickOn(const v1::PickRequest& request, const v1::Scene& scene, const VolumeLease& lease,
                      const VolumeLease* fused) {
  const std::shared_ptr<const Volume>& volume = lease.phase(int(scene.time().phase()));
  v1::Scene framed = scene;
  if (request.has_frame()) {  // the frame the reader saw: the same camera at that size
    const v1::Viewport& f = request.frame();
    if (f.width() < 1 || f.height() < 1 || f.width() > 8192 || f.height() > 8192) {
      throw InputError(fmt::format("frame: {}x{} is outside [1, 8192] each way", f.width(), f.height()));
    }
    framed.mutable_render()->set_width(f.width());
    framed.mutable_render()->set_height(f.height());
  }
  ToVolumeFrame(framed, VolumePlacement::Of(*volume));  // the renderers' frame
  framed.clear_lights();  // a pick follows rays to the first hit: no light, no environment map read
  RenderSetup setup = ResolveScene(framed, *volume, lease.labels().get());
  if (fused && framed.has_fusion()) {
    setup.fused_volume = fused->volume();
    setup.fusion = ResolveFusion(framed.fusion(), *volume, *setup.fused_volume);
  }
  const Picker picker(volume, lease.labels(), setup);
  PickSettings settings;
  if (request.has_threshold()) {
    if (!(request.threshold() > 0 && request.threshold() <= 1)) {
      throw InputError(fmt::format("threshold: {} is outside (0, 1]", request.threshold()));
    }
    settings.threshold = request.threshold();
  }
  if (!(std::isfinite(request.x()) && std::isfinite(request.y()))) throw InputError("x, y: not finite numbers");
  const PickResult hit = picker.PickPixel(int(std::floor(request.x())), int(std::floor(request.y())), settings);
  v1::PickResult out;
  out.set_hit(hit.hit);
  if (!hit.hit) return out;
  ToProto(hit.position_lps, out.mutable_position_mm());
  out.set_value(hit.value);
  if (hit.label) {
    out.mutable_label()->set_value(std::uint32_t(hit.label->value));
    out.mutable_label()->set_name(hit.label->name);
  }
  if (hit.fused_value) out.set_fused_value(*hit.fused_value);
  return out;
}

}  // namespace cinevol::service

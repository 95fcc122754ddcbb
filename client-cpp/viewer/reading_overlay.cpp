// The Reading panel and what the reading tools draw over the views: the
// measurements, the crosshair and the slice planes on the 3D view, the
// orientation marker, a DICOM volume's patient and study in the corners, and
// on each slice its measurements, crosshair, edge letters and position.
#include <fmt/format.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>

#include "viewer/panels.h"
#include "viewer/reading_view.h"

namespace cinevol::viewer {
namespace {

constexpr ImU32 kMeasureColour = IM_COL32(255, 210, 60, 255);
constexpr ImU32 kCrosshairColour = IM_COL32(80, 220, 255, 220);
constexpr float kMarkerRadius = 36;  // logical pixels, the orientation marker's half-axis

// The slice planes on the 3D view in 3D Slicer's colours: axial red,
// coronal green, sagittal yellow (in the order of the panes).
constexpr ImU32 kPlaneColours[] = {IM_COL32(230, 70, 70, 255), IM_COL32(70, 200, 70, 255), IM_COL32(230, 200, 70, 255)};

// The axis colours of 3D Slicer's marker: L/R red, P/A green, S/I blue.
ImU32 AxisColour(char letter) {
  if (letter == 'L' || letter == 'R') return IM_COL32(230, 80, 70, 255);
  if (letter == 'P' || letter == 'A') return IM_COL32(90, 200, 90, 255);
  return IM_COL32(90, 140, 240, 255);
}

}  // namespace

void ReadingPanel(ReadingTools& r, const SessionLink& link) {
  if (ImGui::Button(r.grid ? "3D view only (F3)" : "Slices beside the 3D view (F3)")) r.ToggleGrid();
  const auto& volume = link.volume();
  if (volume && volume->has_identity()) ImGui::Checkbox("patient details in the corners (F4)", &r.identity);
  ImGui::TextWrapped("pick: %s", r.pick_text.empty() ? "click the 3D view" : r.pick_text.c_str());
  if (r.crosshair) ImGui::Text("crosshair: %s", PatientPosition(*r.crosshair).c_str());
  if (ImGui::Button("Measure distance")) r.StartMeasurement(kDistancePoints);
  ImGui::SameLine();
  if (ImGui::Button("Measure angle")) r.StartMeasurement(kAnglePoints);
  if (r.points_wanted > 0) {
    ImGui::Text("point %d of %d...", int(r.points.size()) + 1, r.points_wanted);
    ImGui::SameLine();
    if (ImGui::SmallButton("cancel")) r.CancelMeasurement();
  }
  const auto& measurements = link.shown().scene().measurements();
  int deleted = -1;  // acted on after the list: it changes the list drawn
  for (int i = 0; i < measurements.size(); ++i) {
    const v1::Measurement& m = measurements[i];
    ImGui::PushID(i);
    if (ImGui::SmallButton("x")) deleted = i;
    ImGui::SameLine();
    ImGui::Text("%s: %s", m.name().c_str(), MeasurementText(m).c_str());
    ImGui::PopID();
  }
  if (deleted >= 0) r.DeleteMeasurement(deleted);
}

namespace {

// What the reading overlay draws from.
struct Overlay {
  const ReadingTools& reading;
  const SessionLink& link;
  const Screen& screen;
  float stats_height;  // the stats overlay's, over the identity's top-left corner (0: closed)
};

// A measurement's polyline through `points`, already on screen.
void DrawPolyline(ImDrawList& draw, const std::vector<ImVec2>& points, const std::string& label) {
  for (std::size_t i = 0; i + 1 < points.size(); ++i) draw.AddLine(points[i], points[i + 1], kMeasureColour, 2);
  for (const ImVec2& p : points) draw.AddCircleFilled(p, 3, kMeasureColour);
  if (!points.empty()) draw.AddText({points.back().x + 6, points.back().y - 6}, kMeasureColour, label.c_str());
}

void DrawMeasurementsOn3D(const Overlay& o, const Placement& placement, ImDrawList& draw) {
  const Rect shown = o.screen.ShownFrame();
  if (shown.w <= 0) return;
  const ReadingTools& reading = o.reading;
  const ViewCamera camera = o.link.shown().camera();
  auto on_screen = [&](Vec3d lps) -> std::optional<ImVec2> {
    // Measurements are in patient mm; the camera lives in the volume-centred frame.
    const auto p = ProjectToView(camera, placement.ToVolume(lps), shown.w, shown.h);
    if (!p) return std::nullopt;
    return ImVec2{shown.x + float(p->x), shown.y + float(p->y)};
  };
  if (reading.grid) {  // where the three slices cut the volume
    const Vec3d cross = reading.crosshair.value_or(placement.ToPatient({0, 0, 0}));
    for (std::size_t i = 0; i < reading.panes.size(); ++i) {
      const int axis = CrossedAxis(reading.panes[i].axis);
      std::vector<ImVec2> outline;
      for (const Vec3d& corner : placement.SlicePlaneOutline(axis, cross[axis])) {
        if (const auto p = on_screen(corner)) outline.push_back(*p);
      }
      if (outline.size() >= 3)
        draw.AddPolyline(outline.data(), int(outline.size()), kPlaneColours[i], ImDrawFlags_Closed, 1.5f);
    }
  }
  for (const v1::Measurement& m : o.link.shown().scene().measurements()) {
    std::vector<ImVec2> points;
    for (const v1::Vec3& v : m.points()) {
      if (const auto p = on_screen(ToVec3d(v))) points.push_back(*p);
    }
    if (int(points.size()) == m.points_size()) DrawPolyline(draw, points, MeasurementText(m));
  }
  for (Vec3d pending : reading.points) {
    if (const auto p = on_screen(pending)) draw.AddCircle(*p, 5, kMeasureColour, 0, 2);
  }
  if (reading.crosshair) {
    if (const auto c = on_screen(*reading.crosshair)) {
      draw.AddLine({c->x - 8, c->y}, {c->x + 8, c->y}, kCrosshairColour, 1.5f);
      draw.AddLine({c->x, c->y - 8}, {c->x, c->y + 8}, kCrosshairColour, 1.5f);
    }
  }
}

void DrawOrientationMarker(const Overlay& o, const Placement& placement, ImDrawList& draw) {
  const Rect shown = o.screen.ShownFrame();
  if (shown.w <= 0) return;
  const ImVec2 centre{shown.x + shown.w - kMarkerRadius - 16, shown.y + shown.h - kMarkerRadius - 16};
  for (const MarkerAxis& axis : MarkerAxes(o.link.shown().camera(), placement)) {
    const float x = float(axis.x), y = float(axis.y);
    const ImVec2 end{centre.x + x * kMarkerRadius, centre.y - y * kMarkerRadius};
    const bool near = axis.depth >= 0;  // the half-axes towards the viewer in full, the far ones dim
    const ImU32 colour = near ? AxisColour(axis.letter) : (AxisColour(axis.letter) & 0x80FFFFFF);
    draw.AddLine(centre, end, colour, near ? 3.0f : 1.5f);
    const char text[2] = {axis.letter, 0};
    const ImVec2 size = ImGui::CalcTextSize(text);
    draw.AddText({end.x + x * 8 - size.x / 2, end.y - y * 8 - size.y / 2}, colour, text);
  }
}

// A DICOM volume's patient (top left, below the stats overlay where it is
// open), study and series (top right) in the 3D view's corners.
void DrawIdentity(const Overlay& o, ImDrawList& draw) {
  const Rect shown = o.screen.ShownFrame();
  const auto& volume = o.link.volume();
  if (!o.reading.identity || !volume || !volume->has_identity() || shown.w <= 0) return;
  const IdentityCorners corners = CornersOf(volume->identity());
  const ImU32 colour = IM_COL32(255, 255, 255, 220);
  const float line = ImGui::GetTextLineHeight(), margin = 8;
  const float top = shown.y + margin + (o.stats_height > 0 ? o.stats_height + margin : 0);
  for (std::size_t i = 0; i < corners.top_left.size(); ++i) {
    draw.AddText({shown.x + margin, top + i * line}, colour, corners.top_left[i].c_str());
  }
  for (std::size_t i = 0; i < corners.top_right.size(); ++i) {
    const float width = ImGui::CalcTextSize(corners.top_right[i].c_str()).x;
    draw.AddText({shown.x + shown.w - margin - width, shown.y + margin + i * line}, colour,
                 corners.top_right[i].c_str());
  }
}

void DrawSliceOverlay(const Overlay& o, ImDrawList& draw, int index) {
  const SlicePane& pane = o.reading.panes[index];
  const Rect shown = o.reading.ShownSlice(index);
  if (!pane.image || shown.w <= 0) return;
  const SliceGrid g = SliceGrid::Of(*pane.image);
  const auto placement = o.link.placement();
  const double near_mm = placement ? placement->VoxelStepMm(CrossedAxis(pane.axis)) : 1.0;
  auto on_screen = [&](Vec3d lps) {
    const SlicePixel p = PatientToSlicePixel(g, lps);
    return std::pair{ImVec2{shown.x + float((p.column + 0.5) / g.width) * shown.w,
                            shown.y + float((p.row + 0.5) / g.height) * shown.h},
                     std::fabs(p.off_plane_mm) <= near_mm};
  };
  for (const v1::Measurement& m : o.link.shown().scene().measurements()) {  // those in or near the slice's plane
    std::vector<ImVec2> points;
    bool near = true;
    for (const v1::Vec3& v : m.points()) {
      const auto [p, in_plane] = on_screen(ToVec3d(v));
      points.push_back(p);
      near = near && in_plane;
    }
    if (near) DrawPolyline(draw, points, MeasurementText(m));
  }
  if (o.reading.crosshair) {
    const ImVec2 c = on_screen(*o.reading.crosshair).first;
    draw.AddLine({shown.x, c.y}, {shown.x + shown.w, c.y}, kCrosshairColour & 0x80FFFFFF);
    draw.AddLine({c.x, shown.y}, {c.x, shown.y + shown.h}, kCrosshairColour & 0x80FFFFFF);
  }
  const auto& letters = pane.image->edge_letters();
  if (letters.size() != 4) return;
  const ImU32 white = IM_COL32(255, 255, 255, 230);
  const float mid_x = shown.x + shown.w / 2, mid_y = shown.y + shown.h / 2;
  draw.AddText({shown.x + 4, mid_y - 7}, white, letters[0].c_str());
  draw.AddText({shown.x + shown.w - 14, mid_y - 7}, white, letters[1].c_str());
  draw.AddText({mid_x - 4, shown.y + 4}, white, letters[2].c_str());
  draw.AddText({mid_x - 4, shown.y + shown.h - 18}, white, letters[3].c_str());
  // An axis slice's origin lies in its plane: its coordinate along the crossed axis is the slice's.
  const int axis = CrossedAxis(pane.axis);
  const Rect area = o.screen.pane_area(index);
  draw.AddText({area.x + 6, area.y + 4}, white, fmt::format("{} {:.1f} mm", kPaneNames[index], g.origin[axis]).c_str());
}

}  // namespace

void DrawReadingOverlay(const ReadingTools& reading, const SessionLink& link, const Screen& screen,
                        float stats_height) {
  const Overlay o{reading, link, screen, stats_height};
  ImDrawList& draw = *ImGui::GetBackgroundDrawList();
  // Where the volume lies: the session's state says (a watcher's too), else the volume's description.
  if (const auto placement = link.placement()) {
    DrawMeasurementsOn3D(o, *placement, draw);
    DrawOrientationMarker(o, *placement, draw);
  }
  DrawIdentity(o, draw);
  if (!reading.grid) return;
  for (int pane = 0; pane < Screen::kPanes; ++pane) DrawSliceOverlay(o, draw, pane);
}

}  // namespace cinevol::viewer

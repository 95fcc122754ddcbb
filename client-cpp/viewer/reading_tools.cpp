// The viewer's reading tools (docs/viewer.md, "Reading"): picks on the 3D
// view, the crosshair and the 2x2 layout of slices through it, distance and
// angle measurements, the orientation marker. The geometry is in
// reading_view.h; this file holds what needs the window and the connection.
// Picks and slices go on the connection's quick lane: never behind a still.
#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>

#include "encode/image_codecs.h"
#include "scene/scene_file.h"
#include "viewer/viewer_app.h"

namespace cinevol::viewer {
namespace {

constexpr const char* kAxisNames[] = {"axial", "coronal", "sagittal"};
constexpr ImU32 kMeasureColour = IM_COL32(255, 210, 60, 255);
constexpr ImU32 kCrosshairColour = IM_COL32(80, 220, 255, 220);
constexpr float kMarkerRadius = 36;  // logical pixels, the orientation marker's half-axis

// Fits `w` x `h` (any units) into `area`, centred, keeping the aspect ratio.
Rect Fit(const Rect& area, float w, float h) {
  if (w <= 0 || h <= 0) return {};
  const float s = std::min(area.w / w, area.h / h);
  return {area.x + (area.w - w * s) / 2, area.y + (area.h - h * s) / 2, w * s, h * s};
}

// The slice planes on the 3D view in 3D Slicer's colours: axial red,
// coronal green, sagittal yellow (panes in the order of ReadingState::panes).
constexpr ImU32 kPlaneColours[] = {IM_COL32(230, 70, 70, 255), IM_COL32(70, 200, 70, 255), IM_COL32(230, 200, 70, 255)};

// The axis colours of 3D Slicer's marker: L/R red, P/A green, S/I blue.
ImU32 AxisColour(char letter) {
  if (letter == 'L' || letter == 'R') return IM_COL32(230, 80, 70, 255);
  if (letter == 'P' || letter == 'A') return IM_COL32(90, 200, 90, 255);
  return IM_COL32(90, 140, 240, 255);
}

}  // namespace

// ------------------------------------------------------------------ picks

void App::PickAt(float x, float y) {
  const Rect shown = ShownFrame();
  if (session_id.empty() || !shown.Contains(x, y)) return;
  v1::PickRequest request;
  request.set_session_id(session_id);
  // The frame's pixels are the session's viewport, whatever size it is drawn at.
  request.set_x((x - shown.x) / shown.w * float(texture_w_));
  request.set_y((y - shown.y) / shown.h * float(texture_h_));
  ++reading.busy;
  const std::string unit = volume ? volume->value_unit() : "";
  connection->Request(
      [this, request, unit, generation = reading.generation](Client& client) {
        std::function<void()> then;
        try {
          const v1::PickResult pick = client.Pick(request);
          then = [this, pick, unit] {
            reading.pick = pick;
            reading.pick_text = DescribePick(pick, unit);
            if (!pick.hit()) return;
            AddMeasurementPoint(ToVec3f(pick.position_mm()));
            SetCrosshair(ToVec3f(pick.position_mm()));
          };
        } catch (const std::exception& e) {
          then = [this, text = std::string(e.what())] {
            reading.pick.reset();
            reading.pick_text = "pick: " + text;
          };
        }
        Later([this, generation, then = std::move(then)] {
          if (generation != reading.generation) return;
          --reading.busy;
          then();
          google::protobuf::Struct report;
          (*report.mutable_fields())["hit"].set_bool_value(reading.pick && reading.pick->hit());
          (*report.mutable_fields())["text"] = TextValue(reading.pick_text);
          if (reading.pick) (*report.mutable_fields())["value"] = NumberValue(reading.pick->value());
          Report("pick", report);
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void App::SetCrosshair(Vec3f lps) {
  reading.crosshair = lps;
  if (!reading.grid) return;
  for (int pane = 0; pane < int(reading.panes.size()); ++pane) RequestSlice(pane);
}

// ----------------------------------------------------------------- slices

void App::ToggleGrid() {
  if (Watching()) return;  // slices are the owner's calls
  reading.grid = !reading.grid;
  if (!reading.grid) return;
  // Without a pick yet, the slices go through the volume's centre.
  if (!reading.crosshair && volume) reading.crosshair = VolumePlacement::Of(*volume).PointToPatient({0, 0, 0});
  if (reading.crosshair) SetCrosshair(*reading.crosshair);
}

void App::RequestSlice(int pane) {
  SlicePane& p = reading.panes[pane];
  if (session_id.empty() || !reading.crosshair) return;
  if (p.in_flight) {  // the answer on its way is already old: ask again, once, when it lands
    p.again = true;
    return;
  }
  p.in_flight = true;
  p.again = false;
  ++reading.busy;
  v1::SliceRequest request = CrosshairSlice(session_id, p.axis, *reading.crosshair);
  if (reading.window && reading.level) {
    request.set_window(*reading.window);
    request.set_level(*reading.level);
  }
  connection->Request(
      [this, pane, request, generation = reading.generation](Client& client) {
        std::function<void()> then;
        try {
          v1::SliceImage image = client.RenderSlice(request);
          // Decoded here, off the UI thread; only the texture upload is left to it.
          ImageRgb8 pixels = DecodePng(std::vector<std::uint8_t>(image.png().begin(), image.png().end()));
          image.clear_png();
          then = [this, pane, image = std::move(image), pixels = std::move(pixels)] { ShowSlice(pane, image, pixels); };
        } catch (const std::exception& e) {
          then = [this, text = std::string(e.what())] { notice = "slice: " + text; };
        }
        Later([this, pane, generation, then = std::move(then)] {
          if (generation != reading.generation) return;
          --reading.busy;
          reading.panes[pane].in_flight = false;
          then();
          if (reading.grid && reading.panes[pane].again) RequestSlice(pane);
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void App::ShowSlice(int pane, v1::SliceImage image, const ImageRgb8& pixels) {
  SlicePane& p = reading.panes[pane];
  int w = 0, h = 0;
  if (p.texture) SDL_QueryTexture(p.texture, nullptr, nullptr, &w, &h);
  if (!p.texture || w != pixels.width || h != pixels.height) {
    if (p.texture) SDL_DestroyTexture(p.texture);
    p.texture =
        SDL_CreateTexture(renderer_, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING, pixels.width, pixels.height);
  }
  if (p.texture) SDL_UpdateTexture(p.texture, nullptr, pixels.bytes.data(), pixels.width * 3);
  ++p.received;
  google::protobuf::Struct report;
  (*report.mutable_fields())["axis"] = TextValue(kAxisNames[pane]);
  (*report.mutable_fields())["width"] = NumberValue(image.width());
  (*report.mutable_fields())["height"] = NumberValue(image.height());
  std::string letters;
  for (const std::string& l : image.edge_letters()) letters += l;
  (*report.mutable_fields())["letters"] = TextValue(letters);
  Report("slice", report);
  p.image = std::move(image);
}

void App::StepSlice(int pane, float steps) {
  if (!reading.crosshair || !volume) return;
  const int axis = CrossedAxis(reading.panes[pane].axis);
  Vec3f moved = *reading.crosshair;
  moved[axis] += steps * VoxelStepMm(*volume, axis);
  SetCrosshair(moved);
}

void App::SliceWindowLevel(float dx, float dy) {
  const SlicePane& shown = reading.panes[0];
  if (!reading.window && shown.image) {  // start from what the server applied
    reading.window = shown.image->window();
    reading.level = shown.image->level();
  }
  if (!reading.window) return;
  // As the 3D view's Alt drag: right widens the window, up raises the level.
  reading.window = std::max(1.0f, *reading.window * std::exp(dx * 0.005f));
  reading.level = *reading.level - dy * *reading.window / 200.0f;
  for (int pane = 0; pane < int(reading.panes.size()); ++pane) RequestSlice(pane);
}

void App::ClickSlice(int pane, float x, float y) {
  const SlicePane& p = reading.panes[pane];
  const Rect shown = ShownSlice(p);
  if (!p.image || !shown.Contains(x, y)) return;
  const SliceGeometry g = SliceGeometry::Of(*p.image);
  // Pixel centres at whole numbers: the left edge is column -0.5.
  const float column = (x - shown.x) / shown.w * float(g.width) - 0.5f;
  const float row = (y - shown.y) / shown.h * float(g.height) - 0.5f;
  const Vec3f lps = SlicePixelToPatient(g, column, row);
  AddMeasurementPoint(lps);
  SetCrosshair(lps);
}

Rect App::ShownFrame() const {
  if (!texture_) return {};
  return Fit(frame_area, float(texture_w_), float(texture_h_));
}

Rect App::ShownSlice(const SlicePane& pane) const {
  if (!pane.image) return {};
  // In millimetres, so that a slice of anisotropic voxels keeps its shape.
  return Fit(pane.area, pane.image->width() * pane.image->row_spacing_mm(),
             pane.image->height() * pane.image->column_spacing_mm());
}

int App::SliceAt(float x, float y) const {
  if (!reading.grid) return -1;
  for (int pane = 0; pane < int(reading.panes.size()); ++pane) {
    if (reading.panes[pane].area.Contains(x, y)) return pane;
  }
  return -1;
}

void App::DrawSlices() {
  if (!reading.grid) return;
  for (const SlicePane& pane : reading.panes) {
    const Rect r = ShownSlice(pane);
    if (!pane.texture || r.w <= 0) continue;
    SDL_Rect dst{int(std::lround(r.x * pixel_scale_)), int(std::lround(r.y * pixel_scale_)),
                 int(std::lround(r.w * pixel_scale_)), int(std::lround(r.h * pixel_scale_))};
    SDL_RenderCopy(renderer_, pane.texture, nullptr, &dst);
  }
}

// ----------------------------------------------------------- measurements

void App::StartMeasurement(int points) {
  if (int(reading.measurements.size()) >= kMaxMeasurements) {
    notice = fmt::format("at most {} measurements (a scene holds no more): delete one first", kMaxMeasurements);
    return;
  }
  reading.points_wanted = points;
  reading.points.clear();
  notice = fmt::format("measuring {}: pick {} points on the 3D view or the slices",
                       points == kAnglePoints ? "an angle" : "a distance", points);
}

void App::AddMeasurementPoint(Vec3f lps) {
  if (reading.points_wanted == 0) return;
  reading.points.push_back(lps);
  if (int(reading.points.size()) < reading.points_wanted) return;
  v1::Measurement m;
  for (Vec3f p : reading.points) *m.add_points() = ToProtoVec3(p);
  m.set_name(
      fmt::format("{} {}", m.points_size() == kAnglePoints ? "angle" : "distance", reading.measurements.size() + 1));
  reading.measurements.push_back(m);
  reading.points_wanted = 0;
  reading.points.clear();
  SendMeasurements();
  notice = fmt::format("{}: {}", m.name(), MeasurementText(m));
  google::protobuf::Struct report;
  (*report.mutable_fields())["name"] = TextValue(m.name());
  (*report.mutable_fields())["value"] = TextValue(MeasurementText(m));
  Report("measurement", report);
}

void App::DeleteMeasurement(int index) {
  if (index >= 0 && index < int(reading.measurements.size())) {
    reading.measurements.erase(reading.measurements.begin() + index);
    SendMeasurements();
  }
}

void App::SendMeasurements() {
  v1::SessionEvent e;
  v1::MeasurementList& list = *e.mutable_measurements();  // set even when empty: the last one deleted
  for (const v1::Measurement& m : reading.measurements) *list.add_measurements() = m;
  Post(std::move(e));  // into the session's scene: everyone watching sees them (docs/sharing.md)
}

// ----------------------------------------------------------------- panel

void ReadingPanel(App& app) {
  ReadingState& r = app.reading;
  if (ImGui::Button(r.grid ? "3D view only (F3)" : "Slices beside the 3D view (F3)")) app.ToggleGrid();
  if (app.volume && app.volume->has_identity()) ImGui::Checkbox("patient details in the corners (F4)", &r.identity);
  ImGui::TextWrapped("pick: %s", r.pick_text.empty() ? "click the 3D view" : r.pick_text.c_str());
  if (r.crosshair) ImGui::Text("crosshair: %s", PatientPosition(*r.crosshair).c_str());
  if (ImGui::Button("Measure distance")) app.StartMeasurement(kDistancePoints);
  ImGui::SameLine();
  if (ImGui::Button("Measure angle")) app.StartMeasurement(kAnglePoints);
  if (r.points_wanted > 0) {
    ImGui::Text("point %d of %d...", int(r.points.size()) + 1, r.points_wanted);
    ImGui::SameLine();
    if (ImGui::SmallButton("cancel")) r.points_wanted = 0;
  }
  for (int i = 0; i < int(r.measurements.size()); ++i) {
    const v1::Measurement& m = r.measurements[i];
    ImGui::PushID(i);
    if (ImGui::SmallButton("x")) app.DeleteMeasurement(i);
    ImGui::SameLine();
    ImGui::Text("%s: %s", m.name().c_str(), MeasurementText(m).c_str());
    ImGui::PopID();
  }
}

// ---------------------------------------------------------------- overlay

namespace {

// A measurement's polyline through `points`, already on screen.
void DrawPolyline(ImDrawList& draw, const std::vector<ImVec2>& points, const std::string& label) {
  for (std::size_t i = 0; i + 1 < points.size(); ++i) draw.AddLine(points[i], points[i + 1], kMeasureColour, 2);
  for (const ImVec2& p : points) draw.AddCircleFilled(p, 3, kMeasureColour);
  if (!points.empty()) draw.AddText({points.back().x + 6, points.back().y - 6}, kMeasureColour, label.c_str());
}

void DrawMeasurementsOn3D(App& app, ImDrawList& draw) {
  const Rect shown = app.ShownFrame();
  if (!app.volume || shown.w <= 0) return;
  const VolumePlacement placement = VolumePlacement::Of(*app.volume);
  auto on_screen = [&](Vec3f lps) -> std::optional<ImVec2> {
    // Measurements are in patient mm; the camera lives in the volume-centred frame.
    const auto p = ProjectToView(app.camera, placement.PointToVolume(lps), shown.w, shown.h);
    if (!p) return std::nullopt;
    return ImVec2{shown.x + p->x, shown.y + p->y};
  };
  if (app.reading.grid) {  // where the three slices cut the volume
    const Vec3f cross = app.reading.crosshair.value_or(placement.PointToPatient({0, 0, 0}));
    for (std::size_t i = 0; i < app.reading.panes.size(); ++i) {
      const int axis = CrossedAxis(app.reading.panes[i].axis);
      std::vector<ImVec2> outline;
      for (const Vec3f& corner : SlicePlaneOutline(*app.volume, axis, cross[axis])) {
        if (const auto p = on_screen(corner)) outline.push_back(*p);
      }
      if (outline.size() >= 3)
        draw.AddPolyline(outline.data(), int(outline.size()), kPlaneColours[i], ImDrawFlags_Closed, 1.5f);
    }
  }
  for (const v1::Measurement& m : app.reading.measurements) {
    std::vector<ImVec2> points;
    for (const v1::Vec3& v : m.points()) {
      if (const auto p = on_screen(ToVec3f(v))) points.push_back(*p);
    }
    if (int(points.size()) == m.points_size()) DrawPolyline(draw, points, MeasurementText(m));
  }
  for (Vec3f pending : app.reading.points) {
    if (const auto p = on_screen(pending)) draw.AddCircle(*p, 5, kMeasureColour, 0, 2);
  }
  if (app.reading.crosshair) {
    if (const auto c = on_screen(*app.reading.crosshair)) {
      draw.AddLine({c->x - 8, c->y}, {c->x + 8, c->y}, kCrosshairColour, 1.5f);
      draw.AddLine({c->x, c->y - 8}, {c->x, c->y + 8}, kCrosshairColour, 1.5f);
    }
  }
}

void DrawOrientationMarker(App& app, ImDrawList& draw) {
  const Rect shown = app.ShownFrame();
  if (!app.volume || shown.w <= 0) return;
  const ImVec2 centre{shown.x + shown.w - kMarkerRadius - 16, shown.y + shown.h - kMarkerRadius - 16};
  for (const MarkerAxis& axis : MarkerAxes(app.camera, VolumePlacement::Of(*app.volume))) {
    const ImVec2 end{centre.x + axis.x * kMarkerRadius, centre.y - axis.y * kMarkerRadius};
    const bool near = axis.depth >= 0;  // the half-axes towards the viewer in full, the far ones dim
    const ImU32 colour = near ? AxisColour(axis.letter) : (AxisColour(axis.letter) & 0x80FFFFFF);
    draw.AddLine(centre, end, colour, near ? 3.0f : 1.5f);
    const char text[2] = {axis.letter, 0};
    const ImVec2 size = ImGui::CalcTextSize(text);
    draw.AddText({end.x + axis.x * 8 - size.x / 2, end.y - axis.y * 8 - size.y / 2}, colour, text);
  }
}

// A DICOM volume's patient (top left, below the stats overlay where it is
// open), study and series (top right) in the 3D view's corners.
void DrawIdentity(App& app, ImDrawList& draw) {
  const Rect shown = app.ShownFrame();
  if (!app.reading.identity || !app.volume || !app.volume->has_identity() || shown.w <= 0) return;
  const IdentityCorners corners = CornersOf(app.volume->identity());
  const ImU32 colour = IM_COL32(255, 255, 255, 220);
  const float line = ImGui::GetTextLineHeight(), margin = 8;
  const float top = shown.y + margin + (app.panels.stats ? app.stats_area.h + margin : 0);
  for (std::size_t i = 0; i < corners.top_left.size(); ++i) {
    draw.AddText({shown.x + margin, top + i * line}, colour, corners.top_left[i].c_str());
  }
  for (std::size_t i = 0; i < corners.top_right.size(); ++i) {
    const float width = ImGui::CalcTextSize(corners.top_right[i].c_str()).x;
    draw.AddText({shown.x + shown.w - margin - width, shown.y + margin + i * line}, colour,
                 corners.top_right[i].c_str());
  }
}

void DrawSliceOverlay(App& app, ImDrawList& draw, const SlicePane& pane) {
  const Rect shown = app.ShownSlice(pane);
  if (!pane.image || shown.w <= 0) return;
  const SliceGeometry g = SliceGeometry::Of(*pane.image);
  const float near_mm = app.volume ? VoxelStepMm(*app.volume, CrossedAxis(pane.axis)) : 1.0f;
  auto on_screen = [&](Vec3f lps) {
    const SlicePixel p = PatientToSlicePixel(g, lps);
    return std::pair{ImVec2{shown.x + (p.column + 0.5f) / float(g.width) * shown.w,
                            shown.y + (p.row + 0.5f) / float(g.height) * shown.h},
                     std::fabs(p.off_plane_mm) <= near_mm};
  };
  for (const v1::Measurement& m : app.reading.measurements) {  // those that lie in or near the slice's plane
    std::vector<ImVec2> points;
    bool near = true;
    for (const v1::Vec3& v : m.points()) {
      const auto [p, in_plane] = on_screen(ToVec3f(v));
      points.push_back(p);
      near = near && in_plane;
    }
    if (near) DrawPolyline(draw, points, MeasurementText(m));
  }
  if (app.reading.crosshair) {
    const ImVec2 c = on_screen(*app.reading.crosshair).first;
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
  draw.AddText({pane.area.x + 6, pane.area.y + 4}, white,
               fmt::format("{} {:.1f} mm", kAxisNames[&pane - app.reading.panes.data()], g.origin[axis]).c_str());
}

}  // namespace

void DrawReadingOverlay(App& app) {
  ImDrawList& draw = *ImGui::GetBackgroundDrawList();
  DrawMeasurementsOn3D(app, draw);
  DrawOrientationMarker(app, draw);
  DrawIdentity(app, draw);
  if (!app.reading.grid) return;
  for (const SlicePane& pane : app.reading.panes) DrawSliceOverlay(app, draw, pane);
}

}  // namespace cinevol::viewer

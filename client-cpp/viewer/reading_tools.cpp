// The reading tools' calls and what their answers show.
#include "viewer/reading_tools.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "image_files.h"
#include "viewer/reading_view.h"

namespace cinevol::viewer {

ReadingTools::ReadingTools(ViewerContext& context, SessionLink& link, Screen& screen)
    : context_(context), link_(link), screen_(screen) {}

void ReadingTools::Forget() {
  ++generation_;
  busy_ = 0;
  crosshair.reset();
  pick.reset();
  pick_text.clear();
  for (SlicePane& pane : panes) {
    pane.in_flight = pane.again = false;
    pane.image.reset();
  }
  slices_drawn_from_.clear();
}

void ReadingTools::FollowScene(const v1::Scene& scene) {
  // The server draws the second volume's overlay and the phase into each slice.
  std::string drawn_from = scene.fusion().SerializeAsString() + scene.time().SerializeAsString();
  if (drawn_from == slices_drawn_from_) return;
  slices_drawn_from_ = std::move(drawn_from);
  if (crosshair) SetCrosshair(*crosshair);  // asks only while the slices show
}

// ------------------------------------------------------------------ picks

void ReadingTools::PickAt(float x, float y) {
  const Rect shown = screen_.ShownFrame();
  if (link_.session_id().empty() || !shown.Contains(x, y)) return;
  v1::PickRequest request;
  request.set_session_id(link_.session_id());
  // The frame's pixels are the session's viewport, whatever size it is drawn at.
  request.set_x((x - shown.x) / shown.w * float(screen_.frame_width()));
  request.set_y((y - shown.y) / shown.h * float(screen_.frame_height()));
  ++busy_;
  const std::string unit = link_.volume() ? link_.volume()->value_unit() : "";
  link_.connection().Request(
      [this, request, unit, generation = generation_](Client& client) {
        std::function<void()> then;
        try {
          const v1::PickResult answer = client.Pick(request);
          then = [this, answer, unit] {
            pick = answer;
            pick_text = DescribePick(answer, unit);
            if (!answer.hit()) return;
            AddMeasurementPoint(ToVec3d(answer.position_mm()));
            SetCrosshair(ToVec3d(answer.position_mm()));
          };
        } catch (const std::exception& e) {
          then = [this, text = std::string(e.what())] {
            pick.reset();
            pick_text = "pick: " + text;
          };
        }
        context_.ui.Later([this, generation, then = std::move(then)] {
          if (generation != generation_) return;
          --busy_;
          then();
          google::protobuf::Struct report;
          (*report.mutable_fields())["hit"].set_bool_value(pick && pick->hit());
          (*report.mutable_fields())["text"] = TextValue(pick_text);
          if (pick) (*report.mutable_fields())["value"] = NumberValue(pick->value());
          context_.log.Report("pick", report);
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void ReadingTools::SetCrosshair(Vec3d lps) {
  crosshair = lps;
  if (!grid) return;
  for (int pane = 0; pane < Screen::kPanes; ++pane) RequestSlice(pane);
}

// ----------------------------------------------------------------- slices

void ReadingTools::ToggleGrid() {
  if (link_.Watching()) return;  // slices are the owner's calls
  grid = !grid;
  if (!grid) return;
  // Without a pick yet, the slices go through the volume's centre.
  if (!crosshair) {
    if (const auto placement = link_.placement()) crosshair = placement->ToPatient({0, 0, 0});
  }
  if (crosshair) SetCrosshair(*crosshair);
}

void ReadingTools::RequestSlice(int pane) {
  SlicePane& p = panes[pane];
  if (link_.session_id().empty() || !crosshair) return;
  if (p.in_flight) {  // the answer on its way is already old: ask again, once, when it lands
    p.again = true;
    return;
  }
  p.in_flight = true;
  p.again = false;
  ++busy_;
  v1::SliceRequest request = CrosshairSlice(link_.session_id(), p.axis, *crosshair);
  if (window && level) {
    request.set_window(*window);
    request.set_level(*level);
  }
  link_.connection().Request(
      [this, pane, request, generation = generation_](Client& client) {
        std::function<void()> then;
        try {
          v1::SliceImage image = client.RenderSlice(request);
          // Decoded here, off the UI thread; only the texture upload is left to it.
          RgbImage pixels = DecodePngImage(image.png());
          image.clear_png();
          then = [this, pane, image = std::move(image), pixels = std::move(pixels)] { ShowSlice(pane, image, pixels); };
        } catch (const std::exception& e) {
          then = [this, text = std::string(e.what())] { context_.notice = "slice: " + text; };
        }
        context_.ui.Later([this, pane, generation, then = std::move(then)] {
          if (generation != generation_) return;
          --busy_;
          panes[pane].in_flight = false;
          then();
          if (grid && panes[pane].again) RequestSlice(pane);
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void ReadingTools::ShowSlice(int pane, v1::SliceImage image, const RgbImage& pixels) {
  screen_.UploadSlice(pane, pixels);
  google::protobuf::Struct report;
  (*report.mutable_fields())["axis"] = TextValue(kPaneNames[pane]);
  (*report.mutable_fields())["width"] = NumberValue(image.width());
  (*report.mutable_fields())["height"] = NumberValue(image.height());
  std::string letters;
  for (const std::string& l : image.edge_letters()) letters += l;
  (*report.mutable_fields())["letters"] = TextValue(letters);
  context_.log.Report("slice", report);
  panes[pane].image = std::move(image);
}

void ReadingTools::StepSlice(int pane, float steps) {
  const auto placement = link_.placement();
  if (!crosshair || !placement) return;
  const int axis = CrossedAxis(panes[pane].axis);
  Vec3d moved = *crosshair;
  moved[axis] += steps * placement->VoxelStepMm(axis);
  SetCrosshair(moved);
}

void ReadingTools::WindowLevel(float dx, float dy) {
  const SlicePane& shown = panes[0];
  if (!window && shown.image) {  // start from what the server applied
    window = shown.image->window();
    level = shown.image->level();
  }
  if (!window) return;
  // As the 3D view's Alt drag: right widens the window, up raises the level.
  window = std::max(1.0f, *window * std::exp(dx * 0.005f));
  level = *level - dy * *window / 200.0f;
  for (int pane = 0; pane < Screen::kPanes; ++pane) RequestSlice(pane);
}

void ReadingTools::ClickSlice(int pane, float x, float y) {
  const SlicePane& p = panes[pane];
  const Rect shown = ShownSlice(pane);
  if (!p.image || !shown.Contains(x, y)) return;
  const SliceGrid g = SliceGrid::Of(*p.image);
  // Pixel centres at whole numbers: the left edge is column -0.5.
  const double column = (x - shown.x) / shown.w * g.width - 0.5;
  const double row = (y - shown.y) / shown.h * g.height - 0.5;
  const Vec3d lps = SlicePixelToPatient(g, column, row);
  AddMeasurementPoint(lps);
  SetCrosshair(lps);
}

Rect ReadingTools::ShownSlice(int pane) const {
  const SlicePane& p = panes[pane];
  if (!p.image) return {};
  return Fit(screen_.pane_area(pane), p.image->width() * p.image->row_spacing_mm(),
             p.image->height() * p.image->column_spacing_mm());
}

std::array<Rect, Screen::kPanes> ReadingTools::ShownSlices() const {
  std::array<Rect, Screen::kPanes> shown;
  for (int pane = 0; pane < Screen::kPanes; ++pane) shown[pane] = ShownSlice(pane);
  return shown;
}

// ----------------------------------------------------------- measurements

void ReadingTools::StartMeasurement(int wanted) {
  if (link_.shown().scene().measurements_size() >= kMaxMeasurements) {
    context_.notice = fmt::format("at most {} measurements (a scene holds no more): delete one first", kMaxMeasurements);
    return;
  }
  points_wanted = wanted;
  points.clear();
  context_.notice = fmt::format("measuring {}: pick {} points on the 3D view or the slices",
                                wanted == kAnglePoints ? "an angle" : "a distance", wanted);
}

void ReadingTools::AddMeasurementPoint(Vec3d lps) {
  if (points_wanted == 0) return;
  points.push_back(lps);
  if (int(points.size()) < points_wanted) return;
  const auto& held = link_.shown().scene().measurements();
  std::vector<v1::Measurement> list(held.begin(), held.end());
  v1::Measurement m;
  for (Vec3d p : points) *m.add_points() = ToProto(p);
  m.set_name(fmt::format("{} {}", m.points_size() == kAnglePoints ? "angle" : "distance", list.size() + 1));
  points_wanted = 0;
  points.clear();
  if (!link_.Drives()) {
    context_.notice = "the presenter holds the session's measurements: take the role back to add one";
    return;
  }
  list.push_back(m);
  // Into the session's scene: everyone watching sees it (docs/sharing.md), and a saved scene keeps it.
  link_.shown().SetMeasurements(list);
  context_.notice = fmt::format("{}: {}", m.name(), MeasurementText(m));
  google::protobuf::Struct report;
  (*report.mutable_fields())["name"] = TextValue(m.name());
  (*report.mutable_fields())["value"] = TextValue(MeasurementText(m));
  context_.log.Report("measurement", report);
}

void ReadingTools::DeleteMeasurement(int index) {
  const auto& held = link_.shown().scene().measurements();
  if (index < 0 || index >= held.size()) return;
  std::vector<v1::Measurement> list(held.begin(), held.end());
  list.erase(list.begin() + index);
  link_.shown().SetMeasurements(list);
}

}  // namespace cinevol::viewer

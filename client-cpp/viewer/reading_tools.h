// The reading tools (docs/viewer.md, "Reading"): picks on the 3D view, the
// crosshair and the 2x2 layout of slices through it, the slices' window and
// level, distance and angle measurements (kept in the session's scene). The
// words are in reading_view.h, the geometry in the client library; the
// drawing in reading_overlay.cpp. Picks and slices go on the connection's
// quick lane: never behind a still.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "viewer/screen.h"
#include "viewer/session_link.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

// One slice pane of the 2x2 layout: the slice through the crosshair along one patient axis.
struct SlicePane {
  explicit SlicePane(v1::SliceAxis a) : axis(a) {}

  v1::SliceAxis axis;
  std::optional<v1::SliceImage> image;  // the slice shown: its geometry and letters (its PNG dropped)
  bool in_flight = false;               // one request at a time per pane
  bool again = false;                   // asked meanwhile: the newest position goes next
};

class ReadingTools {
 public:
  ReadingTools(ViewerContext& context, SessionLink& link, Screen& screen);

  // Window positions in logical pixels.
  void PickAt(float x, float y);                // what lies under that point of the 3D view
  void SetCrosshair(Vec3d lps);                 // and the slices through it
  void ToggleGrid();                            // the 2x2 layout and back
  void StepSlice(int pane, float steps);        // by voxels along the pane's axis
  void WindowLevel(float dx, float dy);         // a drag on a slice
  void ClickSlice(int pane, float x, float y);  // crosshair (and measurement point) at that pixel
  void StartMeasurement(int points);            // kDistancePoints or kAnglePoints
  void CancelMeasurement() { points_wanted = 0; }
  void DeleteMeasurement(int index);
  // Where a pane's slice is drawn: in millimetres, so that anisotropic voxels keep their shape.
  Rect ShownSlice(int pane) const;
  std::array<Rect, Screen::kPanes> ShownSlices() const;
  // Another volume: the old one's slices and picks come to nothing.
  void Forget();
  // The server's scene: the slices are asked for again when what they draw from it changed.
  void FollowScene(const v1::Scene& scene);
  bool busy() const { return busy_ > 0; }  // picks and slices under way (a script's settle waits for them)

  // What the panel and the overlay show.
  bool grid = false;                   // the 3D view and three slices (F3)
  bool identity = true;                // a DICOM volume's patient and study in the 3D view's corners (F4)
  std::optional<Vec3d> crosshair;      // LPS mm
  std::optional<v1::PickResult> pick;  // the last pick's answer
  std::string pick_text;               // and in words (or why it failed)
  int points_wanted = 0;               // the measurement being made: 2 distance, 3 angle, 0 none
  std::vector<Vec3d> points;           // its points so far
  std::optional<float> window, level;  // the slices' window/level once dragged; else the server's default
  std::array<SlicePane, Screen::kPanes> panes{SlicePane{v1::AXIAL}, SlicePane{v1::CORONAL}, SlicePane{v1::SAGITTAL}};

 private:
  void RequestSlice(int pane);
  void ShowSlice(int pane, v1::SliceImage image, const RgbImage& pixels);
  void AddMeasurementPoint(Vec3d lps);

  ViewerContext& context_;
  SessionLink& link_;
  Screen& screen_;
  int busy_ = 0;
  std::uint64_t generation_ = 0;  // bumped with Forget: older answers come to nothing
  std::string slices_drawn_from_;  // the parts of the server's scene the slices shown were drawn from
};

// Axial, coronal, sagittal: the panes' names, as scripts write them.
inline constexpr const char* kPaneNames[] = {"axial", "coronal", "sagittal"};

}  // namespace cinevol::viewer

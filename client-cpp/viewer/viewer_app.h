// The viewer's state and UI thread: what the user sees and edits, kept in
// step with the session through the Connection. viewer_app.cpp runs the
// loop, input and scripts; panels.cpp draws the panels and overlay;
// reading_tools.cpp and share_panel.cpp hold the reading and sharing tools.
#pragma once

#include <SDL.h>
#include <google/protobuf/struct.pb.h>

#include <array>
#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/image.h"
#include "local_server.h"
#include "viewer/camera_control.h"
#include "viewer/connection.h"
#include "viewer/reading_view.h"
#include "viewer/sharing_view.h"
#include "viewer/transfer_editor.h"
#include "viewer/viewer.h"

namespace cinevol::viewer {

// JSON values for the lines the viewer reports to scripts (stdout).
inline google::protobuf::Value TextValue(const std::string& text) {
  google::protobuf::Value v;
  v.set_string_value(text);
  return v;
}

inline google::protobuf::Value NumberValue(double number) {
  google::protobuf::Value v;
  v.set_number_value(number);
  return v;
}

using Clock = std::chrono::steady_clock;

// A rectangle in logical (ImGui) pixels.
struct Rect {
  float x = 0, y = 0, w = 0, h = 0;
  bool Contains(float px, float py) const { return px >= x && py >= y && px < x + w && py < y + h; }
};

// What the viewer measures, for the stats overlay and docs/performance.md.
struct ViewerStats {
  std::deque<Clock::time_point> displayed;                      // frames shown in the last second
  std::deque<double> latency_ms;                                // event-to-frame, the last 200 events
  std::deque<std::pair<Clock::time_point, std::size_t>> bytes;  // the last second
  std::uint64_t last_frame_id = 0, dropped = 0;
  double decode_ms = 0, upload_ms = 0, draw_ms = 0;  // the viewer's own cost, last frame
  // Over the whole run, for the summary a script prints at its end (kept
  // only when a script runs: a viewer left open would grow them for ever).
  std::vector<double> all_decode_ms, all_ui_ms, all_latency_ms;  // ui: upload and draw on the UI thread
  std::size_t all_bytes = 0;
  v1::Frame last;                // the newest frame's header
  Clock::time_point last_shown;  // when it arrived

  double Fps() const;
  double LatencyPercentile(double q) const;
  double BytesPerSecond() const;
};

// Panels the user can open and close.
struct PanelsOpen {
  bool volume = true, pacs = false, transfer_function = true, lights = false, render = false, clipping = false,
       labels = false, scene = false, reading = true, share = false;
  bool stats = true;  // the overlay
};

// What the PACS panel shows and edits (docs/viewer.md, "PACS"). Patient
// fields stay here and on screen: they are never printed or logged.
struct PacsBrowser {
  std::vector<std::string> names;  // the server's PACS (ListPacs); none: no panel
  v1::SearchStudiesRequest query;  // the search fields and the PACS searched
  std::vector<v1::StudySummary> studies;
  std::string study_uid;                           // the study selected
  std::vector<v1::SeriesSummary> series;           // of the study selected
  std::string series_uid;                          // the series selected
  std::optional<v1::LoadSeriesProgress> progress;  // of the series being opened
  bool opening = false;
  int busy = 0;  // calls under way (a script's settle waits for them)
  // Bumped when the connection closes: answers of its calls come to nothing.
  std::uint64_t generation = 0;
  std::string source;   // the PACS the studies and series listed came from
  std::string status;   // the panel's status line
  bool failed = false;  // it says what went wrong
};

// One slice pane of the 2x2 layout: the slice through the crosshair along
// one patient axis (docs/viewer.md, "Reading").
struct SlicePane {
  explicit SlicePane(v1::SliceAxis a) : axis(a) {}

  v1::SliceAxis axis;
  Rect area;                            // its quadrant, logical pixels
  std::optional<v1::SliceImage> image;  // the slice shown: its geometry and letters (its PNG dropped)
  SDL_Texture* texture = nullptr;
  bool in_flight = false;  // one request at a time per pane
  bool again = false;      // asked meanwhile: the newest position goes next
  int received = 0;
};

// The reading tools: picks, the crosshair, the 2x2 slices, measurements.
struct ReadingState {
  bool grid = false;                          // the 3D view and three slices (F3)
  bool identity = true;                       // a DICOM volume's patient and study in the 3D view's corners (F4)
  std::optional<Vec3f> crosshair;             // LPS mm
  std::optional<v1::PickResult> pick;         // the last pick's answer
  std::string pick_text;                      // and in words (or why it failed)
  int points_wanted = 0;                      // the measurement being made: 2 distance, 3 angle, 0 none
  std::vector<Vec3f> points;                  // its points so far
  std::vector<v1::Measurement> measurements;  // LPS mm, saved with the scene
  std::optional<float> window, level;         // the slices' window/level once dragged; else the server's default
  std::array<SlicePane, 3> panes{SlicePane{v1::AXIAL}, SlicePane{v1::CORONAL}, SlicePane{v1::SAGITTAL}};
  int busy = 0;                  // picks and slices under way (a script's settle waits for them)
  std::uint64_t generation = 0;  // bumped when the connection closes: older answers come to nothing
};

// Sharing (docs/viewer.md, "Sharing"): the owner's Share panel, and what
// everyone sees of a shared session.
struct ShareForm {
  bool link = true;  // a link; else a grant for `principal`
  std::string principal;
  bool presenter = false;  // the role: presenter, else viewer
  int expiry = 2;          // index into the panel's choices (2 hours)
  bool allow_pointer = false;
};

struct SharingState {
  ShareForm form;                 // the Share panel's
  std::optional<v1::Grant> made;  // the newest grant made here: its secret shows until hidden
  std::vector<v1::Grant> grants;  // ListShares' answer
  std::string status;             // the panel's status line
  bool failed = false;            // it says what went wrong
  int busy = 0;                   // calls under way (a script's settle waits for them)
  std::uint64_t generation = 0;   // bumped when the session changes: older answers come to nothing
  // The session as shared.
  std::optional<v1::SessionState> state;  // the newest: presenter, viewers, pointers
  std::string me;                         // this viewer's name as the server writes it ("": not known yet)
  std::string reported;                   // the last "sharing" line a script was told (it hears of changes only)
  PointerShare pointer;                   // this viewer's pointer over the 3D view
  bool pointer_refused = false;           // the grant does not share it (until the presenter changes)
};

class App {
 public:
  explicit App(ViewerOptions options);
  ~App();
  int Run();

  // --- state the panels read and edit ---------------------------------
  ViewerOptions options;
  std::unique_ptr<cli::LocalServer> local_server;
  std::unique_ptr<Connection> connection;
  std::string session_id;  // of the session the state below belongs to
  std::optional<v1::VolumeInfo> volume;
  ViewCamera camera, home;        // home: where the session started (reset)
  v1::TransferFunction transfer;  // always explicit points in data units
  TransferEditorState editor;
  v1::LightList lights;
  v1::RenderSettings render;  // spp per frame, bounces
  v1::StreamSettings stream;  // denoiser, JPEG quality, target spp
  v1::Clipping clipping;      // the crop box and clip planes (patient mm)
  v1::Labels labels;          // the segmentation's label styles
  PanelsOpen panels;
  ViewerStats stats;
  std::string notice;  // the last message for people (a result or an error)
  // Text fields of the panels.
  std::string load_path, upload_path, scene_path = "view.json", snapshot_path = "snapshot.png";
  int snapshot_spp = 256;
  std::vector<v1::VolumeInfo> server_volumes;
  PacsBrowser pacs;
  ReadingState reading;
  SharingState sharing;

  Rect frame_area, panel_area, stats_area, banner_area;  // banner_area: the line over a shared view (empty: none)

  // --- actions, shared by the panels, the mouse and keys, and scripts ----
  void SendCamera();  // at most once per displayed frame
  void SendTransferFunction();
  void SendLights();
  void SendRender();
  void SendStream();
  void SendClipping();
  void SendLabels();  // where the volume has a segmentation
  void ChoosePreset(const std::string& name);
  void SwitchVolume(const std::string& id);
  void Snapshot(const std::string& path, int spp);
  void SaveScene(const std::string& path);
  void OpenScene(const std::string& path);
  void RefreshVolumes();
  // The PACS panel's calls, on the connection's requester; their answers
  // land in `pacs` (and, in a script run, on stdout without patient fields).
  void SearchPacs(v1::SearchStudiesRequest query);
  void SelectStudy(const std::string& pacs_name, const std::string& study_uid);
  void OpenSeries(const v1::LoadSeriesRequest& request);
  // The reading tools (reading_tools.cpp). Window positions are logical pixels.
  void PickAt(float x, float y);                // what lies under that point of the 3D view
  void SetCrosshair(Vec3f lps);                 // and the slices through it
  void ToggleGrid();                            // the 2x2 layout and back
  void StepSlice(int pane, float steps);        // by voxels along the pane's axis
  void SliceWindowLevel(float dx, float dy);    // a drag on a slice
  void ClickSlice(int pane, float x, float y);  // crosshair (and measurement point) at that pixel
  void StartMeasurement(int points);            // kDistancePoints or kAnglePoints
  void DeleteMeasurement(int index);
  // The measurements into the session's scene (a measurements event), for everyone watching.
  void SendMeasurements();
  Rect ShownFrame() const;                       // where the 3D frame is drawn (empty before one)
  Rect ShownSlice(const SlicePane& pane) const;  // where a pane's slice is drawn
  int SliceAt(float x, float y) const;           // the pane there, or -1
  // Sharing (share_panel.cpp), the owner's calls on the connection's quick
  // lane; their answers land in `sharing` (and, in a script run, on stdout).
  void Share(v1::ShareSessionRequest request);
  void ListShares();
  void Revoke(const std::string& grant_id);
  // Makes a grant the presenter; "": back to the owner (by a presenter's grant: gives the role back).
  void HandOver(const std::string& grant_id);
  bool Watching() const { return !options.grant.empty(); }  // another's session, by a grant
  bool Presents() const;  // this viewer is the presenter (the owner also while nobody else is)
  bool Drives() const;    // its events go to the session now: its own session, or presenting by a grant
  // The mouse over the 3D view, in fractions of the frame; nullopt: it left.
  void PointAt(std::optional<PointerShare::At> at);
  // Runs on the UI thread at the next frame (for results from the worker).
  void Later(std::function<void()> f);

  // Mouse drags and keys, in logical pixels; also what scripts call.
  void Drag(int button, float dx, float dy, SDL_Keymod modifiers);
  void Wheel(float steps);
  bool Key(SDL_Keycode key);

 private:
  // SDL's video; throws InputError (exit 2) where there is no display.
  void OpenDisplay();
  void Connect();
  void AdoptSession();                     // a new session: take its scene, or restore ours onto it
  void ShowScene(const v1::Scene& scene);  // the panels and camera show it
  void Post(v1::SessionEvent event);       // to the session, while this viewer drives
  // Sharing (share_panel.cpp): the newest state (a session another drives is
  // followed), this viewer's pointer, the calls and their answers.
  void FollowSharing();
  void ReportSharing();
  void SharePointer();
  void LearnOwnName();
  void SharingCall(const std::string& action, std::function<std::function<void()>(Client&)> call);
  void Shared(const v1::Grant& grant);
  void SharingFailed(const std::string& action, grpc::StatusCode code, const std::string& message);
  void PumpSdlEvents();
  bool TakeFrame();  // true when a new frame arrived
  void PrintSummary() const;
  void RequestSlice(int pane);
  void ShowSlice(int pane, v1::SliceImage image, const ImageRgb8& pixels);
  void AddMeasurementPoint(Vec3f lps);
  void DrawSlices();
  void Click(int button, float x, float y);  // a press and release without a drag
  std::string RendererName() const;
  void UploadFrame(const ViewFrame& frame);
  void Layout();
  void DrawFrame();
  int Pixels(float logical) const;  // a length of the frame area in frame pixels (at least 16)
  void ResizeViewportWhenSettled();
  bool ResizePending() const;  // the frame area's size is not yet the session's viewport
  void RunScript();
  void RunUiAction(const std::string& json, int line);
  void ListPacs();
  // Runs `call` on the requester; the function it returns (or the error)
  // then runs on the UI thread, unless the connection has closed since.
  void PacsCall(const std::string& action, const std::string& pacs_name,
                std::function<std::function<void()>(Client&)> call);
  void ShowStudies(const v1::SearchStudiesRequest& query, const std::vector<v1::StudySummary>& studies);
  void ShowSeries(const std::string& pacs_name, const std::string& study_uid,
                  const std::vector<v1::SeriesSummary>& series);
  void Opened(const v1::LoadSeriesRequest& request, const v1::VolumeInfo& opened);
  void PacsFailed(const std::string& action, const std::string& pacs_name, grpc::StatusCode code,
                  const std::string& message);
  // One machine-readable line for scripts: "cinevol-viewer: ACTION {JSON}".
  void Report(const std::string& action, const google::protobuf::Struct& fields) const;
  bool EventsAnswered() const;  // every event sent, and the window's size, has its frame on screen
  bool ScriptDone();
  void WriteScreenshot(const std::string& path);

  SDL_Window* window_ = nullptr;
  SDL_Renderer* renderer_ = nullptr;
  SDL_Texture* texture_ = nullptr;
  int texture_w_ = 0, texture_h_ = 0;
  float pixel_scale_ = 1;
  bool camera_dirty_ = false;
  bool quit_ = false;
  int exit_code_ = 0;

  // Viewport resizes wait until the window stops changing.
  int viewport_w_ = 0, viewport_h_ = 0, pending_w_ = 0, pending_h_ = 0;
  Clock::time_point pending_since_;

  // Mouse drag in progress.
  int drag_button_ = 0;
  float drag_x_ = 0, drag_y_ = 0;
  float press_x_ = 0, press_y_ = 0;
  bool dragged_ = false;  // moved far enough since the press to be no click
  int drag_pane_ = -1;    // the slice pane the drag began on, or -1: the 3D view

  // The script: steps with orbits expanded once the volume is known.
  std::optional<cli::SessionScript> script_;
  std::vector<cli::ScriptStep> steps_;
  std::size_t next_step_ = 0;
  std::optional<Clock::time_point> script_start_, settled_since_;
  Clock::time_point last_script_tick_;
  bool finish_now_ = false;               // quit action or out of time: screenshot and stop
  bool settling_ = false;                 // a "settle" action waits for the frame of every event sent
  std::vector<std::string> screenshots_;  // to write once this frame is drawn
  Clock::time_point started_ = Clock::now();

  std::mutex later_mu_;
  std::vector<std::function<void()>> later_;
  std::vector<std::jthread> retired_;  // closing the connections of earlier volumes
};

// panels.cpp
void Hint(const char* text);  // grey help text, wrapped to the panel
void DrawPanels(App& app);
void DrawStatsOverlay(App& app);
void DrawStatusBanner(App& app, const LinkStatus& status);
// reading_tools.cpp
void ReadingPanel(App& app);
void DrawReadingOverlay(App& app);  // measurements, crosshair, orientation marker, slice letters
// share_panel.cpp
void SharePanel(App& app);          // the owner's: share, the grants, hand over, take back
void WatchingPanel(App& app);       // a grant holder's: who presents, give the role back
void DrawSharingOverlay(App& app);  // the line over the view and everyone else's pointers

}  // namespace cinevol::viewer

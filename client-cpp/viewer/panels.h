// The side panel (volume, PACS, time, second volume, transfer function, lights, render,
// clipping, labels, reading, scene, share) and what is drawn over the views (stats,
// the banner that says what is wrong, the line over a shared view, pointers,
// measurements, the orientation marker, the slices' letters). Each panel
// draws one room's state and acts through that room; the edits of the
// session go to the shown session, which sends them.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "viewer/mouse_and_keys.h"
#include "viewer/pacs_browser.h"
#include "viewer/reading_tools.h"
#include "viewer/scene_files.h"
#include "viewer/screen.h"
#include "viewer/session_link.h"
#include "viewer/sharing.h"
#include "viewer/transfer_editor.h"
#include "viewer/viewer_stats.h"

namespace cinevol::viewer {

// The Volume panel's list and fields.
struct VolumeFields {
  std::vector<v1::VolumeInfo> listed;  // the server's volumes, once asked
  std::string load_path, upload_path;
};

// Where the overlays went this turn (logical pixels; empty: not drawn).
struct OverlayAreas {
  Rect stats, banner;  // banner: the line over a shared view
};

// Every room, for what lays them all out (the side panel) or reaches them all (scripts).
struct Rooms {
  ViewerContext& context;
  SessionLink& link;
  Screen& screen;
  ReadingTools& reading;
  PacsBrowser& pacs;
  Sharing& sharing;
  SceneFiles& files;
  ViewerStats& stats;
  PanelsOpen& panels;
  TransferEditorState& editor;
  VolumeFields& volumes;
  OverlayAreas& overlays;
  std::function<void(const std::string&)> switch_volume;  // look at another of the server's volumes
};

// The side panel: every room's panel under its header.
void DrawPanels(Rooms& rooms);
void Hint(const char* text);  // grey help text, wrapped to the panel

// The panels, each given the rooms it shows and acts through (DrawPanels
// calls them under their headers).
// A time series' phase, Play/Pause and rate (Scene.time); while it plays, it
// follows the phase of the frame shown (`last`). Nothing for a still volume.
void TimePanel(SessionLink& link, const v1::Frame& last);
bool IsTimeSeries(const std::optional<v1::VolumeInfo>& volume);  // several phases
// The second volume fused with the session's (Scene.fusion): its name, the
// slices' overlay (opacity, colour map, window) and its glow in 3D.
void FusionPanel(SessionLink& link);
bool Fuses(const v1::Scene& scene);  // a second volume is fused
void TransferPanel(SessionLink& link, TransferEditorState& editor);
void LightsPanel(ShownSession& session);
void RenderPanel(ShownSession& session);
void ClippingPanel(SessionLink& link);
void LabelsPanel(SessionLink& link);
void PacsPanel(PacsBrowser& pacs);
void ReadingPanel(ReadingTools& reading, const SessionLink& link);
void SharePanel(Sharing& sharing, const SessionLink& link);     // the owner's: share, the grants, hand over, take back
void WatchingPanel(Sharing& sharing, const SessionLink& link);  // a grant holder's: who presents, give the role back

// Over the views, in this order (each below the next).
// Measurements, crosshair and slice planes on the 3D view, the marker, a DICOM volume's identity
// (below the stats overlay, `stats_height` tall), the slices' letters and positions.
void DrawReadingOverlay(const ReadingTools& reading, const SessionLink& link, const Screen& screen,
                        float stats_height);
// The line over a shared view (where it went: `banner`) and everyone else's pointers.
void DrawSharingOverlay(const SessionLink& link, const Screen& screen, Rect& banner);
// The stats (F2), below the line of a shared view; where it went in overlays.stats.
void DrawStatsOverlay(const ViewerStats& stats, const Screen& screen, OverlayAreas& overlays, bool open);
// What is wrong, in the middle of the view; nothing while frames keep up.
void DrawStatusBanner(const SessionLink& link, const ViewerStats& stats, const Screen& screen);

}  // namespace cinevol::viewer

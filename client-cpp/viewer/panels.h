// The side panel (volume, PACS, transfer function, lights, render, clipping,
// labels, reading, scene, share) and what is drawn over the views (stats,
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

// The rooms the panels show and act through.
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

void DrawPanels(Rooms& rooms);
void DrawStatsOverlay(Rooms& rooms);
void DrawStatusBanner(Rooms& rooms);
void Hint(const char* text);  // grey help text, wrapped to the panel

// The panels of one room each (panels.cpp calls them under their headers).
void TransferPanel(Rooms& rooms);
void LightsPanel(Rooms& rooms);
void RenderPanel(Rooms& rooms);
void ClippingPanel(Rooms& rooms);
void LabelsPanel(Rooms& rooms);
void PacsPanel(PacsBrowser& pacs);
void ReadingPanel(Rooms& rooms);
void SharePanel(Rooms& rooms);     // the owner's: share, the grants, hand over, take back
void WatchingPanel(Rooms& rooms);  // a grant holder's: who presents, give the role back

// Over the views.
void DrawReadingOverlay(Rooms& rooms);  // measurements, crosshair, slice planes, marker, identity, slice letters
void DrawSharingOverlay(Rooms& rooms);  // the line over the view and everyone else's pointers

}  // namespace cinevol::viewer

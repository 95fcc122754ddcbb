// The viewer's UI thread: it owns the rooms (the session link, the screen,
// the mouse and keys, the reading tools, the PACS browser, sharing, scene
// files, the script) and runs the loop that turns them once a displayed
// frame: input, answers, the session's newest state, the frame, the script,
// then the panels and overlays drawn.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "local_server.h"
#include "viewer/mouse_and_keys.h"
#include "viewer/pacs_browser.h"
#include "viewer/panels.h"
#include "viewer/reading_tools.h"
#include "viewer/scene_files.h"
#include "viewer/screen.h"
#include "viewer/script_runner.h"
#include "viewer/session_link.h"
#include "viewer/sharing.h"
#include "viewer/viewer.h"
#include "viewer/viewer_stats.h"

namespace cinevol::viewer {

class App {
 public:
  explicit App(ViewerOptions options);
  ~App();
  int Run();

 private:
  // Another of the server's volumes: a new session, and nothing of the old one's calls waited for.
  void SwitchVolume(const std::string& volume_id, std::optional<v1::Scene> scene = std::nullopt);
  void Turn();  // one turn of the loop
  bool TakeFrame();  // true when a new frame arrived

  ViewerOptions options_;
  ViewerContext context_;
  std::optional<ScriptRunner> script_;  // before the display: a bad script fails at once
  std::unique_ptr<cli::LocalServer> local_server_;
  std::unique_ptr<Screen> screen_;
  std::unique_ptr<SessionLink> link_;
  ViewerStats stats_;
  PanelsOpen panels_;
  TransferEditorState editor_;
  VolumeFields volumes_;
  OverlayAreas overlays_;
  std::unique_ptr<ReadingTools> reading_;
  std::unique_ptr<PacsBrowser> pacs_;
  std::unique_ptr<Sharing> sharing_;
  std::unique_ptr<SceneFiles> files_;
  std::unique_ptr<MouseAndKeys> input_;
  std::unique_ptr<Rooms> rooms_;
};

}  // namespace cinevol::viewer

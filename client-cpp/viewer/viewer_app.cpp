// The viewer's loop and the order its rooms turn in.
#include "viewer/viewer_app.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <thread>

namespace cinevol::viewer {
namespace {

constexpr auto kFramePeriod = std::chrono::milliseconds(8);  // at most ~120 displayed frames a second

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

}  // namespace

App::App(ViewerOptions options)
    : options_(std::move(options)), context_(!options_.script.empty()), stats_(!options_.script.empty()) {
  if (!options_.script.empty()) script_.emplace(options_, options_.session);
  Screen::OpenDisplay();        // first: without one there is nothing to start a server for
  if (options_.local_server) {  // before the window: a window that waits for it would not answer
    const auto log = std::filesystem::temp_directory_path() / fmt::format("cinevol-viewer-{}.log", getpid());
    std::fprintf(stderr, "cinevol-viewer: starting a local cinevol-server (log: %s)...\n", log.c_str());
    local_server_ = std::make_unique<cli::LocalServer>(options_.backend, log);
    options_.connection.server = local_server_->address();
  }
  screen_ = std::make_unique<Screen>(options_.width, options_.height);
  link_ = std::make_unique<SessionLink>(
      context_, ConnectionSettings{cli::ToClientOptions(options_.connection), options_.session, options_.grant, options_.fuse});
  reading_ = std::make_unique<ReadingTools>(context_, *link_, *screen_);
  pacs_ = std::make_unique<PacsBrowser>(
      context_, *link_, [this](const std::string& id, std::optional<v1::Scene> scene) { SwitchVolume(id, std::move(scene)); });
  sharing_ = std::make_unique<Sharing>(context_, *link_, options_.connection.server, options_.local_server);
  files_ = std::make_unique<SceneFiles>(context_, *link_);
  input_ = std::make_unique<MouseAndKeys>(*link_, *screen_, *reading_, *sharing_, panels_);
  rooms_.reset(new Rooms{context_, *link_, *screen_, *reading_, *pacs_, *sharing_, *files_, stats_, panels_, editor_,
                         volumes_, overlays_, [this](const std::string& id) { SwitchVolume(id); }});
  if (script_) script_->Attach(*rooms_, *input_);
}

App::~App() {
  // The connections' threads stop first (their calls' answers name the rooms),
  // the session closes before the local server stops, and both before the window goes.
  rooms_.reset();
  input_.reset();
  link_.reset();
  files_.reset();
  sharing_.reset();
  pacs_.reset();
  reading_.reset();
  local_server_.reset();
  screen_.reset();
}

void App::SwitchVolume(const std::string& volume_id, std::optional<v1::Scene> scene) {
  link_->SwitchVolume(volume_id, std::move(scene));
  stats_.StartOver();  // a script's settle waits for the new session's first frame
  pacs_->Forget();
  sharing_->Forget();
  reading_->Forget();
  if (!link_->Watching()) pacs_->ListPacs();
}

bool App::TakeFrame() {
  stats_.Age();
  std::optional<ViewFrame> frame = link_->connection().TakeFrame();
  if (!frame) return false;
  stats_.upload_ms = screen_->UploadFrame(frame->image, int(frame->info.width()), int(frame->info.height()));
  stats_.Shown(*frame, link_->connection());
  return true;
}

int App::Run() {
  screen_->Layout(false);
  // The session starts at the size the window shows it.
  link_->Connect(screen_->Pixels(screen_->frame_area().w), screen_->Pixels(screen_->frame_area().h));
  if (!link_->Watching()) pacs_->ListPacs();  // each connection asks: the panel shows only where the server names one
  while (!input_->quit()) Turn();
  if (script_) script_->PrintSummary();
  return script_ ? script_->exit_code() : 0;
}

void App::Turn() {
  const Clock::time_point start = Clock::now();
  input_->Pump();
  context_.ui.RunDue();
  const SessionLink::Turn turn = link_->Update();
  if (turn.new_session) {
    stats_.StartOver();
    sharing_->StartOver();
  }
  sharing_->Follow(turn, panels_.share);
  if (turn.new_state) reading_->FollowScene(link_->shown().server().scene());
  const bool new_frame = TakeFrame();
  if (script_) script_->Tick();
  link_->FollowViewport(screen_->Pixels(screen_->frame_area().w), screen_->Pixels(screen_->frame_area().h));
  link_->FlushCamera();  // one camera event per displayed frame
  sharing_->SharePointer();

  screen_->BeginTurn();
  screen_->Layout(reading_->grid);
  DrawPanels(*rooms_);
  DrawReadingOverlay(*reading_, *link_, *screen_, overlays_.stats.h);
  DrawSharingOverlay(*link_, *screen_, overlays_.banner);
  DrawStatsOverlay(stats_, *screen_, overlays_, panels_.stats);
  DrawStatusBanner(*link_, stats_, *screen_);
  screen_->EndTurn(reading_->grid, reading_->ShownSlices());
  if (script_) {
    script_->WriteScreenshots();
    if (script_->Done()) {
      if (!options_.screenshot.empty()) script_->WriteScreenshot(options_.screenshot);
      input_->Quit();
    }
  }
  screen_->Present();
  if (new_frame) stats_.TurnTook(Ms(Clock::now() - start));  // the UI thread's cost of showing it
  std::this_thread::sleep_until(start + kFramePeriod);
}

int RunViewer(ViewerOptions options) {
  App app(std::move(options));
  return app.Run();
}

}  // namespace cinevol::viewer

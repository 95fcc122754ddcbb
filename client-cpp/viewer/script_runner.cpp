// The script's timeline through the viewer's rooms.
#include "viewer/script_runner.h"

#include <SDL.h>
#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace cinevol::viewer {
namespace {

constexpr double kSettleSeconds = 1.0;  // frames after the last event before the end

}  // namespace

ScriptRunner::ScriptRunner(const ViewerOptions& options, cli::ScriptSession& session)
    : options_(options), script_(cli::LoadScript(options.script)) {
  cli::ScriptSession& s = script_.session;
  const bool names_volume = !s.volume.empty() || !s.load.empty() || !s.upload.empty() || s.series;
  if (!names_volume) s.volume = session.volume, s.load = session.load, s.upload = session.upload;
  if (s.preset.empty() && !s.scene) s.preset = session.preset;
  session = s;
  for (const cli::ScriptStep& step : script_.steps) {
    if (!step.ui.empty()) actions_[step.line] = ParseUiAction(step.ui, fmt::format("{} line {}: ui", options.script, step.line));
  }
}

void ScriptRunner::Attach(Rooms& rooms, MouseAndKeys& input) { target_.emplace(ActionTarget{rooms, input, *this}); }

bool ScriptRunner::Broken() const {
  const LinkState s = target_->rooms.link.status().state;
  return s == LinkState::kFailed || s == LinkState::kReconnecting;
}

void ScriptRunner::Tick() {
  Rooms& r = target_->rooms;
  if (Clock::now() - started_ > std::chrono::duration<double>(options_.max_seconds)) {
    r.context.notice = fmt::format("the script did not finish within {} s (--max-seconds)", options_.max_seconds);
    std::fprintf(stderr, "cinevol-viewer: %s\n", r.context.notice.c_str());
    exit_code_ = 1;
    finish_now_ = true;
    return;
  }
  const Clock::time_point now = Clock::now();
  if (!start_) {
    // It starts with the first frame, or once the server has failed for a
    // second (its UI actions still run: a screenshot shows the message).
    const bool broken = Broken() && now - started_ > std::chrono::seconds(1);
    if (!broken && (r.stats.last_frame_id == 0 || (!r.link.volume() && !r.link.Watching()))) return;
    steps_ = cli::ExpandOrbits(script_.steps, r.link.volume().value_or(v1::VolumeInfo{}));
    start_ = now;
  }
  // The timeline stands still until the view has caught up, or until the
  // server has worked out what a preset or a named view asked of it.
  const bool waiting = (settling_ && !EventsAnswered()) || r.link.shown().Resolving();
  if (waiting && !Broken()) {
    *start_ += now - last_tick_;
    last_tick_ = now;
    return;
  }
  settling_ = false;
  last_tick_ = now;
  const double t = std::chrono::duration<double>(now - *start_).count();
  // A screenshot shows the window as the lines before it left it, so it ends
  // this turn's lines: it is read once this turn is drawn, and a slow turn
  // (a loaded machine) can leave later lines due already, such as a resize.
  while (!settling_ && screenshots_.empty() && !r.link.shown().Resolving() && next_step_ < steps_.size() &&
         steps_[next_step_].at <= t) {
    const cli::ScriptStep& step = steps_[next_step_++];
    if (!step.ui.empty()) {
      actions_.at(step.line)(*target_);
      continue;
    }
    if (!r.link.Drives()) continue;  // no session, or a viewer's: events have nowhere to go
    v1::SessionEvent event = step.event;
    const bool no_points = event.has_transfer_function() && event.transfer_function().points().empty();
    if (no_points && event.transfer_function().preset().empty() && r.link.volume()) {
      event.mutable_transfer_function()->set_preset(r.link.volume()->default_preset());  // as a session naming none
    }
    // The panels show what the lines set, as if they had set it; the server resolves a view or a preset.
    r.link.shown().Send(std::move(event));
  }
}

bool ScriptRunner::EventsAnswered() const {
  const Rooms& r = target_->rooms;
  const Screen& screen = r.screen;
  // A resized window is an event not sent yet (it waits for the window to
  // hold still), and the frame on screen is still of the old size.
  const bool resizing = r.link.ViewportPending(screen.Pixels(screen.frame_area().w), screen.Pixels(screen.frame_area().h));
  if (r.link.shown().camera_waiting() || r.link.shown().Resolving() || resizing || r.stats.last_frame_id == 0 ||
      r.pacs.busy() || r.reading.busy() || r.sharing.busy()) {
    return false;
  }
  // idle() before last_sent(): once nothing waits to be sent, last_sent()
  // counts every event posted; read first, it could miss events sent meanwhile.
  if (!r.link.connection().idle()) return false;
  return r.stats.last.last_event_seq() >= r.link.connection().last_sent();
}

bool ScriptRunner::Done() {
  Rooms& r = target_->rooms;
  const LinkStatus status = r.link.status();
  const bool broken = Broken();
  // A watch the server ended for good (a revoked or expired grant, the
  // session's end) cannot come back: nothing later in the script can run.
  const bool watch_over = r.link.Watching() && status.state == LinkState::kFailed && start_;
  if (finish_now_ || watch_over || (broken && start_ && next_step_ >= steps_.size())) {
    if (broken && exit_code_ == 0) {
      exit_code_ = 3;
      std::fprintf(stderr, "cinevol-viewer: %s\n", status.message.c_str());
    }
    return true;
  }
  if (!start_ || next_step_ < steps_.size() || settling_) return false;
  // Every event answered, then a moment of refinement (or the final frame).
  if (!EventsAnswered()) {
    settled_since_.reset();
    return false;
  }
  if (!settled_since_) settled_since_ = Clock::now();
  return r.stats.last.final() || Clock::now() - *settled_since_ > std::chrono::duration<double>(kSettleSeconds);
}

void ScriptRunner::WriteScreenshots() {
  for (const std::string& file : screenshots_) WriteScreenshot(file);
  screenshots_.clear();
}

void ScriptRunner::WriteScreenshot(const std::string& path) {
  Rooms& r = target_->rooms;
  if (!r.screen.WriteScreenshot(path)) {
    exit_code_ = 1;
    return;
  }
  int w = 0, h = 0;
  r.screen.WindowSize(w, h);
  // Where things are, for whoever checks the screenshot (in its pixels).
  const float scale = r.screen.pixel_scale();
  auto rect = [scale](const Rect& a) {
    return fmt::format("[{:.0f}, {:.0f}, {:.0f}, {:.0f}]", a.x * scale, a.y * scale, a.w * scale, a.h * scale);
  };
  const LinkStatus status = r.link.status();
  std::string escaped;
  for (char c : status.message) escaped += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
  const v1::Frame& last = r.stats.last;
  std::ofstream(std::filesystem::path(path).replace_extension(".layout.json")) << fmt::format(
      "{{\"window\": [{}, {}], \"frame\": {}, \"panel\": {}, \"stats\": {}, \"frameId\": {}, "
      "\"frameSize\": [{}, {}], \"accumulatedSpp\": {}, \"phase\": {}, \"state\": {}, \"message\": \"{}\"}}\n",
      w, h, rect(r.screen.frame_area()), rect(r.screen.panel_area()), r.panels.stats ? rect(r.overlays.stats) : "null",
      last.frame_id(), last.width(), last.height(), last.accumulated_spp(), last.phase(), int(status.state), escaped);
}

void ScriptRunner::PrintSummary() const {
  const double seconds = start_ ? std::chrono::duration<double>(Clock::now() - *start_).count() : 0;
  const Rooms& r = target_->rooms;
  r.stats.PrintSummary(seconds, r.screen.RendererName(), SDL_GetCurrentVideoDriver());
}

}  // namespace cinevol::viewer

// Scripting: a session script played through the window (docs/viewer.md,
// "Scripts"). Its event lines go to the shown session as the panels' edits
// do, its "ui" lines act on the rooms as a person would; "settle" holds the
// timeline until every event sent has its frame, a preset or a named view
// holds it until the server's numbers come, and screenshots (each with a
// layout file beside it) end the turn they are asked in.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "session_script.h"
#include "viewer/ui_actions.h"
#include "viewer/viewer.h"

namespace cinevol::viewer {

class ScriptRunner {
 public:
  // Loads the script and checks every ui action, before any window or
  // server starts. The script's session line names the volume over the
  // command line's; the command line's preset serves where the script names
  // neither a preset nor a scene. `session` becomes what the session starts from.
  ScriptRunner(const ViewerOptions& options, cli::ScriptSession& session);
  // The rooms the actions reach, once they exist.
  void Attach(Rooms& rooms, MouseAndKeys& input);

  // Once a turn, after the frame is taken: runs the lines that are due.
  void Tick();
  // The run is over: every line ran and what it sent has its frame, then a
  // moment of refinement (or the final frame); or it cannot go on.
  bool Done();
  // After the turn is drawn: the screenshots its lines asked for.
  void WriteScreenshots();
  // The window to `path` with `path`.layout.json beside it (where the frame,
  // panel and stats are, in its pixels, and the link's state).
  void WriteScreenshot(const std::string& path);
  void PrintSummary() const;
  int exit_code() const { return exit_code_; }

  // For the actions.
  void Settle() { settling_ = true; }
  void Screenshot(std::string path) { screenshots_.push_back(std::move(path)); }
  void Finish() { finish_now_ = true; }

 private:
  bool EventsAnswered() const;  // every event sent, and the window's size, has its frame on screen
  bool Broken() const;          // refused, or the server cannot be reached (retrying)

  const ViewerOptions& options_;
  cli::SessionScript script_;
  std::map<int, UiAction> actions_;  // by line
  std::optional<ActionTarget> target_;
  std::vector<cli::ScriptStep> steps_;  // with orbits expanded once the volume is known
  std::size_t next_step_ = 0;
  std::optional<Clock::time_point> start_, settled_since_;
  Clock::time_point last_tick_, started_ = Clock::now();
  bool finish_now_ = false;               // quit action or out of time: screenshot and stop
  bool settling_ = false;                 // a "settle" action waits for the frame of every event sent
  std::vector<std::string> screenshots_;  // to write once this turn is drawn
  int exit_code_ = 0;
};

}  // namespace cinevol::viewer

// cinevol-viewer: the window a radiologist looks through. An SDL2 window
// with Dear ImGui panels over a session's frame stream (docs/viewer.md).
#pragma once

#include <string>

#include "connection_options.h"
#include "session_script.h"
#include "viewer/second_volume.h"

namespace cinevol::viewer {

struct ViewerOptions {
  cli::ConnectionOptions connection;
  bool local_server = false;       // no --server: start cinevol-server on the phantom, stop it on exit
  std::string backend = "auto";    // of the local server
  cli::ScriptSession session;      // the volume and the scene or preset to start from
  FuseStart fuse;                  // --fuse: a second volume over it
  std::string grant;               // --grant: watch the shared session it names instead (docs/sharing.md)
  std::string script;              // a session script to play, with UI actions
  std::string screenshot;          // where to write the window when the script ends
  int width = 1280, height = 800;  // window size in logical pixels
  double max_seconds = 120;        // scripts: give up after this long
};

// Opens the window and runs until the user closes it or the script ends.
// Returns the process exit code: 0, 3 when the server refused or could not
// be reached (script mode), 1 when a script ran out of time.
int RunViewer(ViewerOptions options);

}  // namespace cinevol::viewer

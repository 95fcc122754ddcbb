// The mouse and keys as in 3D Slicer (docs/viewer.md, "Mouse and keys"):
// drags over the 3D view orbit, pan and zoom the camera, turn the key light
// or move window and level; over a slice they set its window and level;
// clicks pick or place the crosshair; keys turn to named views, reset the
// view and switch layouts. Scripts' drag, wheel and key actions come here too.
#pragma once

#include <SDL.h>

#include "viewer/reading_tools.h"
#include "viewer/screen.h"
#include "viewer/session_link.h"
#include "viewer/sharing.h"

namespace cinevol::viewer {

// Panels the user can open and close.
struct PanelsOpen {
  bool volume = true, pacs = false, transfer_function = true, lights = false, render = false, clipping = false,
       labels = false, scene = false, reading = true, share = false;
  bool time = true;   // shown only for a time series
  bool fusion = true;  // shown only while a second volume is fused
  bool stats = true;  // the overlay (F2)
};

class MouseAndKeys {
 public:
  MouseAndKeys(SessionLink& link, Screen& screen, ReadingTools& reading, Sharing& sharing, PanelsOpen& panels)
      : link_(link), screen_(screen), reading_(reading), sharing_(sharing), panels_(panels) {}

  // SDL's events since the last turn.
  void Pump();
  // A drag over the 3D view by (dx, dy) logical pixels; a wheel turn; a key.
  void Drag(int button, float dx, float dy, SDL_Keymod modifiers);
  void Wheel(float steps);
  bool Key(SDL_Keycode key);
  void Quit() { quit_ = true; }
  bool quit() const { return quit_; }

 private:
  void Click(int button, float x, float y);  // a press and release without a drag

  SessionLink& link_;
  Screen& screen_;
  ReadingTools& reading_;
  Sharing& sharing_;
  PanelsOpen& panels_;
  bool quit_ = false;
  // The drag in progress.
  int button_ = 0;
  float last_x_ = 0, last_y_ = 0, press_x_ = 0, press_y_ = 0;
  bool dragged_ = false;  // moved far enough since the press to be no click
  int pane_ = -1;         // the slice pane the drag began on, or -1: the 3D view
};

}  // namespace cinevol::viewer

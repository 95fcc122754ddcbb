// The viewer's transfer function editor: an ImGui widget drawing the opacity
// curve over the volume's histogram, with points to drag, add and delete, and
// the selected point's material and the function's global settings below.
#pragma once

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"

namespace cinevol::viewer {

// What the editor remembers between frames; one per editor.
struct TransferEditorState {
  int selected = -1;  // point whose material is edited below the canvas; -1 none
  int dragging = -1;  // point following the mouse while the left button is held; -1 none
};

// Draws the opacity curve over the histogram in the current ImGui window,
// `height` pixels tall and the available width; edits `tf`. Returns true
// when tf changed this frame.
//   left-click a point: select it, and drag to move it (value and opacity)
//   left-click (or double-click) empty space: add a point there and select it
//   right-click a point: delete it (two points always remain)
bool TransferFunctionEditor(const char* id, v1::TransferFunction& tf,
                            const v1::ValueHistogram& histogram, TransferEditorState& state,
                            float height);

}  // namespace cinevol::viewer

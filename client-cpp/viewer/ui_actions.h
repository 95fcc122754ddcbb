// Session-script "ui" lines (docs/viewer.md): each action is checked when the
// script loads (a bad one names its line before anything starts) and becomes
// what running it does to the viewer's rooms.
#pragma once

#include <functional>
#include <string>

#include "viewer/mouse_and_keys.h"
#include "viewer/panels.h"

namespace cinevol::viewer {

class ScriptRunner;

// What an action reaches: the rooms, the mouse and keys as a person's hand,
// and the script's own timeline (settle, screenshot, quit).
struct ActionTarget {
  Rooms& rooms;
  MouseAndKeys& input;
  ScriptRunner& runner;
};
using UiAction = std::function<void(ActionTarget&)>;

// Throws InputError "WHERE.ACTION: what was wrong"; a returned action may
// throw the same when it runs (a point index the transfer function lacks).
UiAction ParseUiAction(const std::string& json, const std::string& where);

}  // namespace cinevol::viewer

// Sharing a session (docs/viewer.md, "Sharing"; docs/sharing.md): the
// owner's grants, hand-over and take-back; what everyone hears of who
// presents and who watches; this viewer's pointer over the 3D view. The calls
// go on the connection's quick lane: never behind a still. The words and the
// pointer's pace are in sharing_view.h; the panels in share_panel.cpp.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "viewer/session_link.h"
#include "viewer/sharing_view.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

const char* RoleName(v1::ShareRole role);  // "presenter" or "viewer"

// The Share panel's fields.
struct ShareForm {
  bool link = true;  // a link; else a grant for `principal`
  std::string principal;
  bool presenter = false;  // the role: presenter, else viewer
  int expiry = 2;          // index into the panel's choices (2 hours)
  bool allow_pointer = false;
};

class Sharing {
 public:
  // `server_address`: where a grant's holder joins; `own_server`: a local
  // server of this viewer's (loopback only).
  Sharing(ViewerContext& context, SessionLink& link, std::string server_address, bool own_server);

  // A new session has no grants (a restarted server forgot them); the
  // server says who owns it, which is how presenter and pointers name it.
  void StartOver();
  // The session changes: answers about the old one come to nothing.
  void Forget();
  // Once a turn, after the link's update: hears the newest state (who
  // presents, who watches, whose pointers), tells a script of changes and,
  // where the Share panel is open, lists the grants again when they change.
  void Follow(const SessionLink::Turn& turn, bool panel_open);
  // The mouse over the 3D view, in fractions of the frame; nullopt: it left.
  void PointAt(std::optional<PointerShare::At> at) { pointer_.MoveTo(at); }
  // Sends this viewer's pointer when it is due (while anyone watches).
  void SharePointer();

  // The owner's calls; their answers land here (and, in a script run, on stdout).
  void Share(v1::ShareSessionRequest request);
  void ListShares();
  void Revoke(const std::string& grant_id);
  // Makes a grant the presenter; "": back to the owner (by a presenter's grant: gives the role back).
  void HandOver(const std::string& grant_id);
  bool busy() const { return busy_ > 0; }  // calls under way (a script's settle waits for them)

  const std::string& server_address() const { return server_address_; }
  bool own_server() const { return own_server_; }

  // What the panels show and edit.
  ShareForm form;
  std::optional<v1::Grant> made;  // the newest grant made here: its secret shows until hidden
  std::vector<v1::Grant> grants;  // ListShares' answer
  std::string status;             // the panel's status line
  bool failed = false;            // it says what went wrong

 private:
  void Call(const std::string& action, std::function<std::function<void()>(Client&)> call);
  void Shared(const v1::Grant& grant);
  void Failed(const std::string& action, grpc::StatusCode code, const std::string& message);
  void Report(const v1::SessionState& state);

  ViewerContext& context_;
  SessionLink& link_;
  const std::string server_address_;
  const bool own_server_;
  int busy_ = 0;
  std::uint64_t generation_ = 0;  // bumped when the session changes: older answers come to nothing
  bool seen_ = false;             // a state was heard since the stream went live
  std::string presenter_;         // as the last state said
  std::uint32_t viewers_ = 0;
  std::string reported_;      // the last "sharing" line a script was told (it hears of changes only)
  PointerShare pointer_;      // this viewer's pointer over the 3D view
  bool pointer_refused_ = false;  // the grant does not share it (until the presenter changes)
};

}  // namespace cinevol::viewer

// What a session is, seen from the client that created it: the server's last
// word on its state (ServerMessage.state) and the events sent since that the
// server has not answered yet. When the session's server goes away, the
// stream creates the session again on another server from that state and
// sends those events again (failover). The client never works out what an
// event does: the server does (server/scene/session_state.h).
#pragma once

#include <cstdint>
#include <map>
#include <vector>

#include "cinevol/v1/service.pb.h"

namespace cinevol {

class SessionState {
 public:
  // `request` as sent and the server's answer (its scene has the defaults
  // filled and a named view's camera resolved).
  SessionState(const v1::CreateSessionRequest& request, const v1::CreateSessionResponse& created);

  // An event went out on the session's stream.
  void Sent(const v1::SessionEvent& event);
  // The server's state arrived: it includes every event up to its
  // last_event_seq, which the stream no longer needs to keep.
  void Adopt(const v1::SessionState& state);
  // A new stream attached to the same session (sequence numbers start again):
  // what the old stream sent is the server's now, answered or not.
  void Reattached();

  // The request that creates the session again as the server last had it.
  v1::CreateSessionRequest request() const;
  // The events to send after `request()`: a pause where the session was
  // paused, then what the server never answered.
  std::vector<v1::SessionEvent> Unanswered() const;
  // A session created from request() is attached to: nothing is pending.
  void Recreated();

 private:
  v1::CreateSessionRequest request_;  // volume_id, viewport, scene and stream as the server last had them
  bool paused_ = false;
  // Sent on the current stream, newer than the last state: one per kind, as
  // the server coalesces them (the latest wins; render and stream settings
  // merge; pause and resume are one kind), so a server that never answers
  // costs a few events, not one per event sent.
  std::map<int, v1::SessionEvent> unanswered_;
};

}  // namespace cinevol

// What a session is, seen from the client that created it: the request that
// would create it again as it is now. The client library keeps one for each
// session it creates and applies every event its stream sends, so that when
// the session's server goes away the stream can re-create the session on
// another server from its last scene (failover).
#pragma once

#include <string>

#include "cinevol/v1/service.pb.h"

namespace cinevol {

class SessionState {
 public:
  // `request` as sent and the server's answer (its scene has the defaults
  // filled and a named view's camera resolved).
  SessionState(const v1::CreateSessionRequest& request, const v1::CreateSessionResponse& created);

  // Applies an event the way the server does: a camera, lights, transfer
  // function, clipping or labels replace the scene's; render and stream
  // settings change the fields they set; resize changes the viewport.
  void Apply(const v1::SessionEvent& event);

  // The request that re-creates the session as it is now.
  const v1::CreateSessionRequest& request() const { return request_; }
  // Paused by its last pause or resume event: a re-created session pauses too.
  bool paused() const { return paused_; }

 private:
  v1::CreateSessionRequest request_;  // `scene` always set
  bool paused_ = false;
};

}  // namespace cinevol

#include "session_state.h"

#include <algorithm>

namespace cinevol {

SessionState::SessionState(const v1::CreateSessionRequest& request, const v1::CreateSessionResponse& created)
    : request_(request) {
  *request_.mutable_scene() = created.scene();
  request_.mutable_scene()->clear_volume();  // volume_id says which
}

void SessionState::Sent(const v1::SessionEvent& event) {
  const int kind = event.has_resume() ? int(v1::SessionEvent::kPause) : int(event.kind_case());
  auto [it, fresh] = unanswered_.try_emplace(kind, event);
  if (fresh) return;
  if (event.has_render() || event.has_stream()) {
    it->second.MergeFrom(event);  // set fields change; the seq is the newest
  } else {
    it->second = event;
  }
}

void SessionState::Adopt(const v1::SessionState& state) {
  *request_.mutable_scene() = state.scene();
  *request_.mutable_stream() = state.stream();
  *request_.mutable_viewport() = state.viewport();
  paused_ = state.paused();
  std::erase_if(unanswered_, [&](const auto& kind_event) { return kind_event.second.seq() <= state.last_event_seq(); });
}

void SessionState::Reattached() { unanswered_.clear(); }

v1::CreateSessionRequest SessionState::request() const { return request_; }

std::vector<v1::SessionEvent> SessionState::Unanswered() const {
  std::vector<v1::SessionEvent> events;
  if (paused_) events.emplace_back().mutable_pause();
  for (const auto& [kind, event] : unanswered_) events.push_back(event);
  return events;
}

void SessionState::Recreated() {
  unanswered_.clear();
  paused_ = false;
}

}  // namespace cinevol

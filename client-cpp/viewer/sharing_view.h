// What the viewer shows of a shared session, without a window (docs/viewer.md,
// "Sharing"): the line over the view, the names the server writes for a
// grant's holder, and the pointer a viewer shares at a bounded rate.
// web/src/share.ts and pointers.ts are the browser's twins of these.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "cinevol/v1/service.pb.h"

namespace cinevol::viewer {

// The grant id in a grant's secret ("cvg_<id>_<key>"); "" when it is none.
std::string GrantIdOf(const std::string& secret);
// A grant's holder as the server names it (SessionState.presenter, a
// pointer's who): its principal, or "link <id>" for a link.
std::string HolderName(const v1::Grant& grant);
// A grant holder's own name before the echo of its pointer says otherwise:
// that of a link ("link <id>"); a principal's grant is named after the
// principal, which only the echo tells.
std::string GuessedHolderName(const std::string& secret);
// The name the server gave the pointer sent at exactly (x, y): one's own
// name, where exactly one pointer lies there.
std::optional<std::string> EchoedName(const v1::SessionState& state, float x, float y);

// The line over the view: who presents and how many watch. `presenting`:
// this viewer's name is the presenter; `by_grant`: it watches another's
// session. Empty for one's own session that nobody watches.
std::string PresenceLine(const v1::SessionState& state, bool presenting, bool by_grant);
// How long until a grant expires, in words: "in 2 h 5 min", "in 40 s", "expired".
std::string ExpiresIn(std::int64_t expires_unix_seconds, std::int64_t now_unix_seconds);

// The pointer a viewer shares: where the mouse is over the frame, at most
// one move per `period` (the newest waits, older ones are dropped), and a
// hidden pointer once the mouse leaves (only after a shown one).
class PointerShare {
 public:
  using Clock = std::chrono::steady_clock;
  struct At {
    float x = 0, y = 0;  // [0, 1] of the frame's width and height
    bool operator==(const At&) const = default;
  };

  PointerShare() = default;
  explicit PointerShare(Clock::duration period) : period_(period) {}
  // The mouse at `at` over the frame; nullopt: it left.
  void MoveTo(std::optional<At> at);
  // The pointer event due at `now`, if one is.
  std::optional<v1::Pointer> Due(Clock::time_point now);
  // Where the last shown pointer went (none: hidden, or nothing sent).
  std::optional<At> sent() const { return sent_; }

 private:
  Clock::duration period_ = std::chrono::milliseconds(50);  // at most 20 moves a second
  std::optional<At> at_, sent_;
  bool changed_ = false;
  std::optional<Clock::time_point> last_;
};

}  // namespace cinevol::viewer

// The words and names of a shared session, and the pointer's pace.
#include "viewer/sharing_view.h"

#include <fmt/format.h>

namespace cinevol::viewer {

std::string GrantIdOf(const std::string& secret) {
  constexpr std::string_view kPrefix = "cvg_";
  if (!secret.starts_with(kPrefix)) return {};
  const std::size_t end = secret.find('_', kPrefix.size());
  return end == std::string::npos ? std::string() : secret.substr(kPrefix.size(), end - kPrefix.size());
}

std::string HolderName(const v1::Grant& grant) {
  return grant.principal().empty() ? "link " + grant.id() : grant.principal();
}

std::string GuessedHolderName(const std::string& secret) {
  const std::string id = GrantIdOf(secret);
  return id.empty() ? std::string() : "link " + id;
}

std::optional<std::string> EchoedName(const v1::SessionState& state, float x, float y) {
  std::optional<std::string> name;
  for (const v1::SharedPointer& p : state.pointers()) {
    if (p.x() != x || p.y() != y) continue;
    if (name) return std::nullopt;  // two at one place: neither is surely ours
    name = p.who();
  }
  return name;
}

std::string PresenceLine(const v1::SessionState& state, bool presenting, bool by_grant) {
  const std::string watching = fmt::format("{} viewer{}", state.viewers(), state.viewers() == 1 ? "" : "s");
  const std::string presenter = state.presenter().empty() ? "the owner" : state.presenter();
  if (by_grant) return presenting ? "You present · " + watching : fmt::format("Watching {} · {}", presenter, watching);
  if (presenting) return state.viewers() == 0 ? "" : "Shared · " + watching;
  return fmt::format("{} presents · {} (Share: Take back)", presenter, watching);
}

std::string ExpiresIn(std::int64_t expires_unix_seconds, std::int64_t now_unix_seconds) {
  const std::int64_t left = expires_unix_seconds - now_unix_seconds;
  if (left <= 0) return "expired";
  if (left < 60) return fmt::format("in {} s", left);
  const std::int64_t minutes = (left + 30) / 60, hours = minutes / 60, days = hours / 24;
  if (days >= 1) return fmt::format("in {} d {} h", days, hours % 24);
  return hours >= 1 ? fmt::format("in {} h {} min", hours, minutes % 60) : fmt::format("in {} min", minutes);
}

void PointerShare::MoveTo(std::optional<At> at) {
  at_ = at;
  changed_ = at_ != sent_;
}

std::optional<v1::Pointer> PointerShare::Due(Clock::time_point now) {
  if (!changed_ || (last_ && now - *last_ < period_)) return std::nullopt;
  changed_ = false;
  v1::Pointer pointer;
  if (at_) {
    pointer.set_x(at_->x);
    pointer.set_y(at_->y);
  } else {
    pointer.set_hidden(true);
  }
  sent_ = at_;
  last_ = now;
  return pointer;
}

}  // namespace cinevol::viewer

// Shares of sessions (docs/sharing.md): a grant lets a principal, or whoever
// holds a link's secret, watch a session (viewer) or drive it (presenter).
// Grants live in the server's memory, as sessions do: checked on every call
// like tokens, gone when they expire, are revoked or their session ends.
#pragma once

#include <chrono>
#include <cstddef>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace cinevol::service {

// `bytes` random bytes (getrandom) as lower-case hex.
std::string RandomHex(std::size_t bytes);

enum class GrantRole { kViewer, kPresenter };
const char* ToString(GrantRole role);  // "viewer", "presenter"

struct Grant {
  using Clock = std::chrono::steady_clock;
  using SystemClock = std::chrono::system_clock;

  std::string id;  // "g" + 16 hex: what lists and revocations name; not a credential
  std::string session_id;
  std::string created_by;  // the principal that shared the session
  std::string principal;   // who may use it (their own token signs them in); empty: a link
  GrantRole role = GrantRole::kViewer;
  bool allow_pointer = false;  // the holder's pointer is shared (a presenter's always is)
  Clock::time_point expires;
  SystemClock::time_point expires_wall;  // the same, for people and answers

  bool link() const { return principal.empty(); }
  // Who watches by it, for people: the principal, or "link gXXXX".
  std::string holder() const { return link() ? "link " + id : principal; }
};

class GrantRegistry {
 public:
  explicit GrantRegistry(int max_grants_per_principal) : max_per_principal_(max_grants_per_principal) {}

  // Records `grant` (id and expiry aside, which it sets from `lifetime`) and
  // returns it with its secret: "cvg_<id>_<32 hex>" (128 random bits), the
  // only time the secret is seen. Throws LimitExceeded past
  // --max-grants-per-principal grants created by grant.created_by.
  // With `restore_secret` ("cvg_<id>_<key>", made by another server), the
  // grant keeps that id and secret; InputError for a malformed one, or an id
  // this server already holds.
  std::pair<Grant, std::string> Create(Grant grant, std::chrono::seconds lifetime,
                                       const std::string& restore_secret = {});

  // The unexpired grant `secret` names, compared in constant time; nullopt
  // for a malformed, unknown, expired or revoked one.
  std::optional<Grant> FindBySecret(const std::string& secret) const;
  std::optional<Grant> Find(const std::string& id) const;
  // The unexpired grants of `session_id`, oldest first.
  std::vector<Grant> OfSession(const std::string& session_id) const;
  // Forgets the grant; false when there was none.
  bool Revoke(const std::string& id);
  // Sets the grant's role (the presenter role handed over); false when there is none.
  bool SetRole(const std::string& id, GrantRole role);
  // Forgets and returns the grants past their expiry.
  std::vector<Grant> TakeExpired();
  // Forgets the grants of a session that ended.
  void ForgetSession(const std::string& session_id);

 private:
  struct Entry {
    Grant grant;
    std::string key;  // the secret's random part
  };
  const int max_per_principal_;
  mutable std::mutex mu_;
  std::map<std::string, Entry> grants_;  // by id
};

}  // namespace cinevol::service

// The grants of shared sessions, in memory.
#include "runtime/grants.h"

#include <fmt/format.h>
#include <openssl/crypto.h>
#include <sys/random.h>

#include <algorithm>
#include <cerrno>
#include <system_error>
#include <tuple>

#include "core/error.h"
#include "runtime/errors.h"

namespace cinevol::service {
namespace {

constexpr std::string_view kSecretPrefix = "cvg_";

bool IsHex(std::string_view s) { return !s.empty() && s.find_first_not_of("0123456789abcdef") == std::string::npos; }

// "cvg_g<16 hex>_<32 hex>" as its id and key; nullopt for anything else.
std::optional<std::pair<std::string, std::string>> SplitSecret(const std::string& secret) {
  if (!secret.starts_with(kSecretPrefix)) return std::nullopt;
  const std::size_t split = secret.find('_', kSecretPrefix.size());
  if (split == std::string::npos) return std::nullopt;
  std::string id = secret.substr(kSecretPrefix.size(), split - kSecretPrefix.size());
  std::string key = secret.substr(split + 1);
  if (id.size() != 17 || id[0] != 'g' || !IsHex(std::string_view(id).substr(1)) || key.size() != 32 || !IsHex(key)) {
    return std::nullopt;
  }
  return std::pair{std::move(id), std::move(key)};
}

}  // namespace

std::string RandomHex(std::size_t bytes) {
  std::vector<unsigned char> random(bytes);
  for (std::size_t got = 0; got < bytes;) {
    const ssize_t n = getrandom(random.data() + got, bytes - got, 0);
    if (n < 0 && errno != EINTR) throw std::system_error(errno, std::generic_category(), "getrandom");
    if (n > 0) got += std::size_t(n);
  }
  std::string hex;
  for (unsigned char b : random) hex += fmt::format("{:02x}", b);
  return hex;
}

const char* ToString(GrantRole role) { return role == GrantRole::kPresenter ? "presenter" : "viewer"; }

std::pair<Grant, std::string> GrantRegistry::Create(Grant grant, std::chrono::seconds lifetime,
                                                    const std::string& restore_secret) {
  grant.id = fmt::format("g{}", RandomHex(8));  // "g" + a temporary draws a false -Wrestrict from GCC 12 at -O3
  std::string key = RandomHex(16);
  if (!restore_secret.empty()) {
    const auto parts = SplitSecret(restore_secret);
    if (!parts) throw InputError("restore_secret: not a grant's secret (cvg_<id>_<32 hex>)");
    std::tie(grant.id, key) = *parts;
  }
  grant.expires = Grant::Clock::now() + lifetime;
  grant.expires_wall = Grant::SystemClock::now() + lifetime;
  std::lock_guard lock(mu_);
  if (grants_.count(grant.id)) throw InputError(fmt::format("restore_secret: grant {} is held here already", grant.id));
  const auto created = std::count_if(grants_.begin(), grants_.end(), [&](const auto& entry) {
    return entry.second.grant.created_by == grant.created_by;
  });
  if (created >= max_per_principal_) {
    throw LimitExceeded("max-grants-per-principal",
                        fmt::format("you have {} grants, this server's limit (--max-grants-per-principal): revoke "
                                    "one first",
                                    created));
  }
  grants_[grant.id] = {grant, key};
  return {grant, fmt::format("{}{}_{}", kSecretPrefix, grant.id, key)};
}

std::optional<Grant> GrantRegistry::FindBySecret(const std::string& secret) const {
  // "cvg_<id>_<key>": the id finds the entry, the key is compared in constant time.
  const auto parts = SplitSecret(secret);
  if (!parts) return std::nullopt;
  const auto& [id, key] = *parts;
  std::lock_guard lock(mu_);
  const auto it = grants_.find(id);
  if (it == grants_.end() || it->second.key.size() != key.size()) return std::nullopt;
  if (CRYPTO_memcmp(it->second.key.data(), key.data(), key.size()) != 0) return std::nullopt;
  if (Grant::Clock::now() >= it->second.grant.expires) return std::nullopt;
  return it->second.grant;
}

std::optional<Grant> GrantRegistry::Find(const std::string& id) const {
  std::lock_guard lock(mu_);
  const auto it = grants_.find(id);
  if (it == grants_.end() || Grant::Clock::now() >= it->second.grant.expires) return std::nullopt;
  return it->second.grant;
}

std::vector<Grant> GrantRegistry::OfSession(const std::string& session_id) const {
  std::vector<Grant> out;
  const auto now = Grant::Clock::now();
  std::lock_guard lock(mu_);
  for (const auto& [id, entry] : grants_) {
    if (entry.grant.session_id == session_id && now < entry.grant.expires) out.push_back(entry.grant);
  }
  std::sort(out.begin(), out.end(), [](const Grant& a, const Grant& b) { return a.expires_wall < b.expires_wall; });
  return out;
}

bool GrantRegistry::Revoke(const std::string& id) {
  std::lock_guard lock(mu_);
  return grants_.erase(id) > 0;
}

bool GrantRegistry::SetRole(const std::string& id, GrantRole role) {
  std::lock_guard lock(mu_);
  const auto it = grants_.find(id);
  if (it == grants_.end()) return false;
  it->second.grant.role = role;
  return true;
}

std::vector<Grant> GrantRegistry::TakeExpired() {
  std::vector<Grant> out;
  const auto now = Grant::Clock::now();
  std::lock_guard lock(mu_);
  for (auto it = grants_.begin(); it != grants_.end();) {
    if (now >= it->second.grant.expires) {
      out.push_back(it->second.grant);
      it = grants_.erase(it);
    } else {
      ++it;
    }
  }
  return out;
}

void GrantRegistry::ForgetSession(const std::string& session_id) {
  std::lock_guard lock(mu_);
  std::erase_if(grants_, [&](const auto& entry) { return entry.second.grant.session_id == session_id; });
}

}  // namespace cinevol::service

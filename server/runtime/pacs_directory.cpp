// PacsDirectory: names to DICOMweb clients.
#include "runtime/pacs_directory.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <set>

#include "core/error.h"
#include "core/log_safe.h"
#include "runtime/errors.h"

namespace cinevol::service {

PacsDirectory::PacsDirectory(std::vector<pacs::PacsConfig> configs, std::filesystem::path credentials_file)
    : configs_(std::move(configs)), credentials_file_(std::move(credentials_file)) {
  std::set<std::string> names;
  for (const pacs::PacsConfig& c : configs_) {
    if (!names.insert(c.name).second) throw InputError(fmt::format("--pacs: '{}' is named twice", c.name));
  }
  std::map<std::string, pacs::PacsCredentials> credentials;
  if (!credentials_file_.empty()) credentials = pacs::LoadCredentialsFile(credentials_file_);
  for (const auto& [name, unused] : credentials) {
    if (!names.count(name)) {
      throw InputError(fmt::format("--pacs-credentials: names PACS '{}', which no --pacs names", LogSafe(name, 64)));
    }
  }
  for (const pacs::PacsConfig& c : configs_) {
    if (c.credentials.kind == pacs::PacsCredentials::Kind::kForward && credentials.count(c.name)) {
      throw InputError(fmt::format("--pacs-credentials: names PACS '{}', which takes the caller's token "
                                   "(--pacs-auth forward): one or the other",
                                   c.name));
    }
  }
  std::lock_guard lock(mu_);
  BuildClientsLocked(credentials);
}

void PacsDirectory::BuildClientsLocked(const std::map<std::string, pacs::PacsCredentials>& credentials) {
  std::map<std::string, std::shared_ptr<const pacs::DicomWebClient>> clients;
  for (pacs::PacsConfig config : configs_) {
    const bool forwards = config.credentials.kind == pacs::PacsCredentials::Kind::kForward;
    if (auto it = credentials.find(config.name); it != credentials.end() && !forwards) config.credentials = it->second;
    const std::string name = config.name;  // the right side is evaluated first, and moves `config`
    clients[name] = std::make_shared<const pacs::DicomWebClient>(std::move(config));
  }
  clients_ = std::move(clients);  // calls under way keep the clients they found
}

std::shared_ptr<const pacs::DicomWebClient> PacsDirectory::Find(const std::string& name, const Principal& caller,
                                                                const char* field) const {
  std::shared_ptr<const pacs::DicomWebClient> found;
  {
    std::lock_guard lock(mu_);
    if (auto it = clients_.find(name); it != clients_.end()) found = it->second;
  }
  if (found && found->config().credentials.kind == pacs::PacsCredentials::Kind::kForward) {
    if (caller.bearer_token.empty()) {
      throw RpcError::Unauthenticated(fmt::format("{}: PACS '{}' takes the caller's own token (--pacs-auth forward); "
                                                  "send the metadata 'authorization: Bearer <token>'",
                                                  field, name));
    }
    pacs::PacsConfig config = found->config();
    config.credentials = pacs::ForwardedCredentials(caller.bearer_token);
    return std::make_shared<const pacs::DicomWebClient>(std::move(config));  // for this call only
  }
  if (found) return found;
  if (configs_.empty()) throw InputError(fmt::format("{}: this server names no PACS (--pacs NAME=URL)", field));
  throw InputError(fmt::format("{}: no PACS named '{}'; this server names {} (a PACS is named, never given by URL)",
                               field, LogSafe(name, 64), fmt::join(Names(), ", ")));
}

std::vector<std::string> PacsDirectory::Names() const {
  std::vector<std::string> names;
  for (const pacs::PacsConfig& c : configs_) names.push_back(c.name);
  return names;
}

bool PacsDirectory::ReloadCredentials() {
  if (credentials_file_.empty()) return true;
  try {
    const auto credentials = pacs::LoadCredentialsFile(credentials_file_);
    std::lock_guard lock(mu_);
    BuildClientsLocked(credentials);
    spdlog::info("pacs: credentials reloaded from {} ({} PACS)", credentials_file_.string(), credentials.size());
    return true;
  } catch (const std::exception& e) {
    spdlog::error("pacs: credentials not reloaded, the old ones stay: {}", LogSafe(e.what()));
    return false;
  }
}

}  // namespace cinevol::service

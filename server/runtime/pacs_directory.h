// The PACS this server's operator named (--pacs NAME=URL), by name: what a
// request's `pacs` field is looked up in, so no URL from a request is ever
// fetched. Credentials come from one file (--pacs-credentials), reloaded on
// SIGHUP; a reload that fails keeps the credentials in use.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "pacs/dicomweb_client.h"
#include "runtime/principal.h"

namespace cinevol::service {

class PacsDirectory {
 public:
  PacsDirectory() = default;
  // Checks every configuration and reads the credentials file (InputError
  // naming the option, the PACS or the file's line).
  PacsDirectory(std::vector<pacs::PacsConfig> configs, std::filesystem::path credentials_file);

  // The client for PACS `name` acting for `caller` (with their bearer token
  // where the PACS takes it: --pacs-auth forward; UNAUTHENTICATED when the
  // call carried none); InputError naming the field `field` and the
  // configured names when there is none (a URL in its place included).
  std::shared_ptr<const pacs::DicomWebClient> Find(const std::string& name, const Principal& caller,
                                                   const char* field = "pacs") const;
  std::vector<std::string> Names() const;
  bool empty() const { return configs_.empty(); }

  // Re-reads the credentials file; false (logged, nothing changed) when it
  // cannot be read or parsed. Without a credentials file it does nothing.
  bool ReloadCredentials();

 private:
  void BuildClientsLocked(const std::map<std::string, pacs::PacsCredentials>& credentials);

  std::vector<pacs::PacsConfig> configs_;
  std::filesystem::path credentials_file_;
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<const pacs::DicomWebClient>> clients_;  // by name
};

}  // namespace cinevol::service

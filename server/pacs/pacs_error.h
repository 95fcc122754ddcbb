// What a PACS did wrong, as an exception the service maps to a status.
#pragma once

#include <stdexcept>
#include <string>

namespace cinevol::pacs {

// A PACS failed, refused or answered what DICOMweb does not promise: it could
// not be reached or did not answer in time, answered an HTTP error or a
// redirect, or sent a body that is not what was asked for. The message names
// the PACS and what was asked; never a secret, a URL or a patient's data.
// (Limits a PACS's answer breaks are OverLimit; cancellation is Cancelled;
// bad input from the caller is InputError: see core/error.h.)
class PacsError : public std::runtime_error {
 public:
  explicit PacsError(const std::string& what, long http_status = 0)
      : std::runtime_error(what), http_status_(http_status) {}
  // The HTTP status the PACS answered with, or 0 where there was no HTTP answer.
  long http_status() const { return http_status_; }
  // The PACS refused cinevol's credentials (401) or their rights (403).
  bool refused_credentials() const { return http_status_ == 401 || http_status_ == 403; }

 private:
  long http_status_;
};

}  // namespace cinevol::pacs

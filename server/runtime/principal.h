// Who a call acts for: the name a token or a client certificate gave it
// (service/auth.h decides), which the runtime records as the owner of what
// it creates and checks before it hands a session or a volume over.
#pragma once

#include <string>

namespace cinevol::service {

struct Principal {
  std::string name;
  bool is_operator = false;
  // The bearer token the call carried, as given: only for a PACS that takes
  // the caller's own (--pacs-auth forward). Never logged.
  std::string bearer_token = {};
};

// Throws RpcError(PERMISSION_DENIED) unless `caller` is `owner`.
void RequireOwner(const Principal& caller, const std::string& owner, const std::string& what);

}  // namespace cinevol::service

// RequireOwner: the one check of who may touch a session or a volume.
#include "runtime/principal.h"

#include <fmt/format.h>

#include "runtime/errors.h"

namespace cinevol::service {

void RequireOwner(const Principal& caller, const std::string& owner, const std::string& what) {
  if (caller.name != owner) {
    throw RpcError::PermissionDenied(fmt::format("{} belongs to another user", what));
  }
}

}  // namespace cinevol::service

// Authentication: bearer tokens from a file, or open.
#include "service/auth.h"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

#include "service/errors.h"

namespace cinevol::service {

Authenticator::Authenticator(const std::filesystem::path& token_file) {
  std::ifstream in(token_file);
  if (!in) throw InputError(fmt::format("--auth-tokens {}: cannot read the file", token_file.string()));
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    std::istringstream fields(line);
    std::string token, principal, extra;
    fields >> token;
    if (token.empty() || token[0] == '#') continue;
    fields >> principal >> extra;
    if (principal.empty() || !extra.empty()) {
      throw InputError(fmt::format("--auth-tokens {} line {}: expected 'TOKEN PRINCIPAL'", token_file.string(),
                                   number));
    }
    principals_[token] = principal;
  }
  if (principals_.empty()) {
    throw InputError(fmt::format("--auth-tokens {}: no tokens (lines of 'TOKEN PRINCIPAL')", token_file.string()));
  }
}

Principal Authenticator::Authenticate(const grpc::CallbackServerContext& context) const {
  if (principals_.empty()) return {"anonymous"};
  const auto& metadata = context.client_metadata();
  const auto header = metadata.find("authorization");
  constexpr std::string_view kBearer = "Bearer ";
  const std::string_view value =
      header == metadata.end() ? std::string_view() : std::string_view(header->second.data(), header->second.size());
  if (!value.starts_with(kBearer)) {
    throw RpcError(grpc::StatusCode::UNAUTHENTICATED,
                   "this server needs a token: send the metadata 'authorization: Bearer <token>'");
  }
  const auto it = principals_.find(value.substr(kBearer.size()));
  if (it == principals_.end()) throw RpcError(grpc::StatusCode::UNAUTHENTICATED, "the bearer token is not valid");
  return {it->second};
}

void RequireOwner(const Principal& caller, const std::string& owner, const std::string& what) {
  if (caller.name != owner) {
    throw RpcError(grpc::StatusCode::PERMISSION_DENIED, fmt::format("{} belongs to another user", what));
  }
}

}  // namespace cinevol::service

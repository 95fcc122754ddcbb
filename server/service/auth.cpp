// Authentication: bearer tokens from a file, client certificates, or open.
// Tokens are kept only as SHA-256 digests and compared in constant time
// (CRYPTO_memcmp over every entry), so neither memory nor timing gives one away.
#include "service/auth.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <grpcpp/security/auth_context.h>
#include <openssl/crypto.h>
#include <openssl/sha.h>
#include <spdlog/spdlog.h>

#include <array>
#include <cctype>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <vector>

#include "runtime/errors.h"

namespace cinevol::service {

using Digest = std::array<unsigned char, SHA256_DIGEST_LENGTH>;

namespace {

Digest Hash(std::string_view token) {
  Digest digest{};
  SHA256(reinterpret_cast<const unsigned char*>(token.data()), token.size(), digest.data());
  return digest;
}

// The first 8 bytes of `digest` in hex: a name for a token that is not the token.
std::string HexPrefix(const Digest& digest) {
  return fmt::format("{:02x}", fmt::join(digest.begin(), digest.begin() + 8, ""));
}

struct Entry {
  Digest digest;
  Principal principal;
};
using Entries = std::vector<Entry>;

std::shared_ptr<const Entries> Load(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(fmt::format("--auth-tokens {}: cannot read the file", file.string()));
  auto entries = std::make_shared<Entries>();
  std::map<Digest, int> line_of;  // duplicate tokens are an error
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    std::istringstream fields(line);
    std::string token, principal, role, extra;
    fields >> token;
    if (token.empty() || token[0] == '#') continue;
    fields >> principal >> role >> extra;
    if (principal.empty() || !extra.empty() || (!role.empty() && role != "operator")) {
      throw InputError(fmt::format("--auth-tokens {} line {}: expected 'TOKEN PRINCIPAL' or 'TOKEN PRINCIPAL operator'",
                                   file.string(), number));
    }
    const Digest digest = Hash(token);
    if (const auto [it, fresh] = line_of.emplace(digest, number); !fresh) {
      throw InputError(fmt::format("--auth-tokens {} line {}: the same token as line {}", file.string(), number,
                                   it->second));
    }
    entries->push_back({digest, {principal, role == "operator"}});
  }
  if (in.bad()) throw InputError(fmt::format("--auth-tokens {}: cannot read the file", file.string()));
  if (entries->empty()) {
    throw InputError(fmt::format("--auth-tokens {}: no tokens (lines of 'TOKEN PRINCIPAL [operator]')", file.string()));
  }
  return entries;
}

// Every token file in use, so that SIGHUP reaches the one inside the server.
std::mutex registry_mu;
std::vector<std::weak_ptr<Authenticator::TokenFile>>& Registry() {
  static auto* registry = new std::vector<std::weak_ptr<Authenticator::TokenFile>>;
  return *registry;
}

std::string_view View(const grpc::string_ref& s) { return {s.data(), s.size()}; }

}  // namespace

struct Authenticator::TokenFile {
  explicit TokenFile(std::filesystem::path p) : path(std::move(p)), entries(Load(path)) {}

  std::shared_ptr<const Entries> Current() const {
    std::lock_guard lock(mu);
    return entries;
  }
  void Reload() {
    std::shared_ptr<const Entries> loaded = Load(path);  // throws: the old ones stay
    std::lock_guard lock(mu);
    entries = std::move(loaded);
  }

  const std::filesystem::path path;
  mutable std::mutex mu;
  std::shared_ptr<const Entries> entries;
};

Authenticator::Authenticator(const std::filesystem::path& token_file)
    : tokens_(std::make_shared<TokenFile>(token_file)) {
  std::lock_guard lock(registry_mu);
  auto& registry = Registry();
  std::erase_if(registry, [](const auto& weak) { return weak.expired(); });
  registry.push_back(tokens_);
}

void Authenticator::Reload() {
  if (tokens_) tokens_->Reload();
}

std::size_t Authenticator::token_count() const { return tokens_ ? tokens_->Current()->size() : 0; }

Principal Authenticator::Authenticate(const grpc::CallbackServerContext& context) const {
  const std::shared_ptr<const grpc::AuthContext> auth_context = context.auth_context();
  const auto& metadata = context.client_metadata();
  // Two principals' tokens in one call: which one names the caller would be
  // a guess, so neither does.
  if (const std::size_t headers = metadata.count("authorization"); headers > 1) {
    throw RpcError::Unauthenticated(fmt::format("the call carries {} 'authorization' headers; send one", headers));
  }
  const auto header = metadata.find("authorization");
  std::optional<std::string> authorization;
  if (header != metadata.end()) authorization.emplace(header->second.data(), header->second.size());
  return Authenticate(auth_context.get(), authorization ? &*authorization : nullptr);
}

Principal Authenticator::Authenticate(const grpc::AuthContext* auth_context, const std::string* authorization) const {
  // A client certificate reaches the server only under mutual TLS, which
  // requires and verifies it (tls.cpp); plain TLS does not ask for one.
  std::optional<std::string> certificate_name;
  if (auth_context != nullptr) {
    const auto names = auth_context->FindPropertyValues("x509_common_name");
    const bool has_certificate =
        !names.empty() || !auth_context->FindPropertyValues("x509_pem_cert").empty();
    if (has_certificate) {
      if (names.empty() || names.front().empty()) {
        throw RpcError::Unauthenticated("the client certificate has no subject common name (CN) to name the caller");
      }
      certificate_name.emplace(View(names.front()));
    }
  }
  constexpr std::string_view kBearer = "bearer ";
  const std::string_view value = authorization ? std::string_view(*authorization) : std::string_view();
  const bool bearer = value.size() > kBearer.size() &&
                      std::equal(kBearer.begin(), kBearer.end(), value.begin(),
                                 [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); });
  const std::string_view token = bearer ? value.substr(kBearer.size()) : std::string_view();
  if (!tokens_) {
    Principal open{certificate_name.value_or("anonymous"), false};
    if (forwards_tokens_ && bearer) {
      if (!certificate_name) open.name = "bearer:" + HexPrefix(Hash(token));
      open.bearer_token = std::string(token);
    }
    return open;
  }
  if (!bearer) {
    throw RpcError::Unauthenticated("this server needs a token: send the metadata 'authorization: Bearer <token>'");
  }
  const Digest digest = Hash(token);
  const std::shared_ptr<const Entries> entries = tokens_->Current();
  const Entry* match = nullptr;
  for (const Entry& entry : *entries) {  // every entry, whatever matched
    const bool equal = CRYPTO_memcmp(entry.digest.data(), digest.data(), digest.size()) == 0;
    match = equal ? &entry : match;
  }
  if (match == nullptr) throw RpcError::Unauthenticated("the bearer token is not valid");
  Principal known = match->principal;
  if (forwards_tokens_) known.bearer_token = std::string(token);
  return known;
}

bool ReloadAllTokenFiles() {
  std::vector<std::shared_ptr<Authenticator::TokenFile>> files;
  {
    std::lock_guard lock(registry_mu);
    for (const auto& weak : Registry()) {
      if (auto file = weak.lock()) files.push_back(std::move(file));
    }
  }
  if (files.empty()) spdlog::info("SIGHUP: no --auth-tokens file to reload");
  bool ok = true;
  for (const auto& file : files) {
    try {
      file->Reload();
      spdlog::info("reloaded {} tokens from {}", file->Current()->size(), file->path.string());
    } catch (const std::exception& e) {
      ok = false;
      spdlog::error("{}; the tokens loaded before stay in use", e.what());
    }
  }
  return ok;
}

}  // namespace cinevol::service

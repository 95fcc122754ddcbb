// TLS credentials and the listen policy. The PEM files are checked with
// OpenSSL (the library gRPC itself links) so that a bad file is reported at
// start, naming its flag, rather than as a server that cannot listen.
#include "service/tls.h"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <grpcpp/security/server_credentials.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <iterator>
#include <system_error>

#include "core/error.h"

namespace cinevol::service {
namespace {

std::string ReadPem(const std::filesystem::path& file, const char* flag) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    throw InputError(fmt::format("{} {}: no such file", flag, file.string()));
  }
  std::ifstream in(file, std::ios::binary);
  std::string text(std::istreambuf_iterator<char>(in), {});
  if (!in && !in.eof()) throw InputError(fmt::format("{} {}: cannot read the file", flag, file.string()));
  if (text.empty()) throw InputError(fmt::format("{} {}: the file is empty (PEM expected)", flag, file.string()));
  return text;
}

struct BioFree {
  void operator()(BIO* b) const { BIO_free(b); }
};
struct X509Free {
  void operator()(X509* x) const { X509_free(x); }
};
struct KeyFree {
  void operator()(EVP_PKEY* k) const { EVP_PKEY_free(k); }
};
using BioPtr = std::unique_ptr<BIO, BioFree>;
using X509Ptr = std::unique_ptr<X509, X509Free>;
using KeyPtr = std::unique_ptr<EVP_PKEY, KeyFree>;

BioPtr MemoryBio(const std::string& text) { return BioPtr(BIO_new_mem_buf(text.data(), int(text.size()))); }

// A password callback that gives none: encrypted keys fail instead of
// prompting on the terminal.
int NoPassword(char*, int, int, void*) { return 0; }

// The certificates of a PEM text, in order.
std::vector<X509Ptr> ParseCertificates(const std::string& pem) {
  std::vector<X509Ptr> certs;
  BioPtr bio = MemoryBio(pem);
  while (X509* cert = PEM_read_bio_X509(bio.get(), nullptr, NoPassword, nullptr)) certs.emplace_back(cert);
  ERR_clear_error();  // the read past the last one
  return certs;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

}  // namespace

std::shared_ptr<grpc::ServerCredentials> MakeServerCredentials(const TlsOptions& tls) {
  if (!tls.enabled()) return grpc::InsecureServerCredentials();
  if (tls.cert.empty() || tls.key.empty()) {
    throw InputError(tls.mutual() ? "--tls-client-ca needs --tls-cert and --tls-key (the server's own certificate)"
                                  : "--tls-cert and --tls-key go together: give both");
  }
  const std::string cert_pem = ReadPem(tls.cert, "--tls-cert");
  const std::string key_pem = ReadPem(tls.key, "--tls-key");
  const std::vector<X509Ptr> chain = ParseCertificates(cert_pem);
  if (chain.empty()) {
    throw InputError(fmt::format("--tls-cert {}: no PEM certificate in the file", tls.cert.string()));
  }
  BioPtr key_bio = MemoryBio(key_pem);
  KeyPtr key(PEM_read_bio_PrivateKey(key_bio.get(), nullptr, NoPassword, nullptr));
  ERR_clear_error();
  if (!key) {
    throw InputError(fmt::format("--tls-key {}: no PEM private key in the file (encrypted keys are not supported)",
                                 tls.key.string()));
  }
  if (X509_check_private_key(chain.front().get(), key.get()) != 1) {
    ERR_clear_error();
    throw InputError(fmt::format("--tls-key {} does not belong to the certificate of --tls-cert {}", tls.key.string(),
                                 tls.cert.string()));
  }

  grpc::SslServerCredentialsOptions options(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  options.pem_key_cert_pairs.push_back({key_pem, cert_pem});
  if (tls.mutual()) {
    const std::string ca_pem = ReadPem(tls.client_ca, "--tls-client-ca");
    if (ParseCertificates(ca_pem).empty()) {
      throw InputError(fmt::format("--tls-client-ca {}: no PEM certificate in the file", tls.client_ca.string()));
    }
    options.pem_root_certs = ca_pem;
    options.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(options);
}

bool IsLoopbackListen(const std::string& listen) {
  if (listen.starts_with("unix:") || listen.starts_with("unix-abstract:")) return true;  // not on the network
  std::string address = listen;
  for (const char* scheme : {"ipv4:", "ipv6:"}) {
    if (address.starts_with(scheme)) address.erase(0, std::string_view(scheme).size());
  }
  std::string host = address;
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    host = close == std::string::npos ? std::string() : host.substr(1, close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos) {
    // "::1" alone is an address with no port; anything else with one colon is HOST:PORT.
    in6_addr six{};
    if (inet_pton(AF_INET6, host.c_str(), &six) != 1) host = host.substr(0, colon);
  }
  host = Lower(host);
  if (host == "localhost" || host == "localhost.") return true;
  in_addr four{};
  if (inet_pton(AF_INET, host.c_str(), &four) == 1) {
    return (ntohl(four.s_addr) >> 24) == 127;
  }
  in6_addr six{};
  if (inet_pton(AF_INET6, host.c_str(), &six) == 1) {
    if (IN6_IS_ADDR_LOOPBACK(&six)) return true;
    return IN6_IS_ADDR_V4MAPPED(&six) && six.s6_addr[12] == 127;
  }
  return false;  // a host name, an empty host or a wildcard: reachable from elsewhere
}

void CheckListenPolicy(const std::string& listen, bool has_tokens, bool has_mutual_tls, bool insecure_no_auth) {
  if (has_tokens || has_mutual_tls || insecure_no_auth || IsLoopbackListen(listen)) return;
  throw InputError(fmt::format(
      "--listen {} is reachable from other machines, but callers would not be authenticated. Give "
      "--auth-tokens FILE (bearer tokens; with --tls-cert/--tls-key so they do not travel in clear), or mutual TLS "
      "with --tls-cert/--tls-key/--tls-client-ca, or --insecure-no-auth to let anyone who can reach the port in",
      listen));
}

}  // namespace cinevol::service

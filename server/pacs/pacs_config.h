// The PACS an operator names (`--pacs NAME=URL`), their limits, and their
// credentials file. A client names a PACS by NAME only; every request goes to
// a URL built from that PACS's base URL, never to one from a request.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>

namespace cinevol::pacs {

// How cinevol proves who it is to one PACS. The secrets live here and in the
// credentials file only: never in a URL, a log line or an exception message.
struct PacsCredentials {
  // kForward: each call carries the caller's own bearer token (--pacs-auth
  // forward): the directory's configuration has none, a call's client the
  // caller's (ForwardedCredentials).
  enum class Kind { kNone, kBasic, kBearer, kForward };
  Kind kind = Kind::kNone;
  std::string user;      // kBasic
  std::string password;  // kBasic
  std::string token;     // kBearer, kForward
};

// `token`, the caller's bearer token, as the credentials of one call to a
// PACS that takes it. InputError unless it is an RFC 6750 token (1 to 8192 of
// A-Z a-z 0-9 - . _ ~ + /, then '='s): nothing else reaches a header.
PacsCredentials ForwardedCredentials(std::string_view token);

// One DICOMweb service. Every field has a default a hospital network can live
// with; ValidatePacsConfig names the field that is out of its range.
struct PacsConfig {
  // [A-Za-z0-9_-], 1 to 64 characters: how requests, messages and metrics name this PACS.
  std::string name;
  // The DICOMweb root, http:// or https://, without user info, query or fragment, stored without a trailing
  // slash (e.g. "https://pacs.example.org/dicom-web"). Requests go to this URL plus escaped UIDs only.
  std::string base_url;
  PacsCredentials credentials;
  // A PEM file of CA certificates to verify an https PACS with; empty: the system's store.
  std::string ca_file;
  // [100 ms; 60 s] - setting up one connection (TCP and TLS).
  std::chrono::milliseconds connect_timeout{5000};
  // [100 ms; 1 h] - the whole of one HTTP request: a search, one instance, one store.
  std::chrono::milliseconds request_timeout{120000};
  // [1 KiB; 4 GiB] bytes - the largest body of one answer (one instance's multipart); the transfer is aborted
  // as soon as it passes this, and before it starts when the PACS announces a larger Content-Length.
  std::uint64_t max_response_bytes = std::uint64_t{1} << 30;
  // [1 KiB; 256 MiB] bytes - the largest search answer (DICOM JSON): parsing costs several times its size.
  std::uint64_t max_json_bytes = std::uint64_t{16} << 20;
  // [1; 100000] - the most instances of one retrieved series; a larger series is refused before any is fetched.
  std::size_t max_instances = 4096;
  // [1 KiB; 64 GiB] bytes - the most bytes of one retrieved series, all instances together, counted as they
  // arrive (the transfers in flight are aborted when it is passed); also the most one store may send.
  std::uint64_t max_series_bytes = std::uint64_t{4} << 30;
  // [1; 32] - instances of one series fetched at once.
  int parallel_fetches = 4;
  // [1; 5000] - the most studies or series one search returns; a query's limit is capped by it.
  int max_search_results = 200;
};

// Throws InputError naming the first field of `config` outside its range.
void ValidatePacsConfig(const PacsConfig& config);

// True for 1 to 64 characters of [A-Za-z0-9_-].
bool IsValidPacsName(std::string_view name);

// `NAME=URL` (the `--pacs` option) as a configuration with the defaults above.
// Refuses (InputError) a bad name, a URL that is not http:// or https://, user
// info in the URL (credentials belong in the credentials file), a query or a
// fragment.
PacsConfig ParsePacsSpec(std::string_view spec);

// The base URL `url` checked and normalised (scheme in lower case, no trailing
// slash); InputError as ParsePacsSpec.
std::string NormaliseBaseUrl(std::string_view url);

// A credentials file's text, one PACS a line:
//   NAME basic USER:PASSWORD
//   NAME bearer TOKEN
// with blank lines and `#` comments. Errors (InputError) name `source` and the
// line number, never the line's text: it may hold a secret.
std::map<std::string, PacsCredentials> ParseCredentials(std::string_view text, std::string_view source);

// ParseCredentials over the regular file at `path` (at most 1 MiB).
std::map<std::string, PacsCredentials> LoadCredentialsFile(const std::filesystem::path& path);

}  // namespace cinevol::pacs

// Parsing and checking what the operator says about each PACS.
#include "pacs/pacs_config.h"

#include <curl/curl.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <memory>
#include <sstream>
#include <vector>

#include "core/error.h"

namespace cinevol::pacs {
namespace {

using std::chrono::milliseconds;

template <class T>
void CheckRange(std::string_view field, T value, T low, T high) {
  if (value < low || value > high) {
    throw InputError(fmt::format("PACS configuration: {} is {}, outside [{}; {}]", field, value, low, high));
  }
}

void CheckDuration(std::string_view field, milliseconds value, milliseconds low, milliseconds high) {
  CheckRange(field, value.count(), low.count(), high.count());
}

bool HasControlOrSpace(std::string_view text) {
  return std::any_of(text.begin(), text.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u <= 0x20 || u == 0x7f;
  });
}

// One part of a URL parsed by libcurl; empty when the URL has none.
std::string UrlPart(CURLU* url, CURLUPart part) {
  char* value = nullptr;
  if (curl_url_get(url, part, &value, 0) != CURLUE_OK || value == nullptr) return {};
  std::string text(value);
  curl_free(value);
  return text;
}

std::string_view Trim(std::string_view text) {
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.remove_suffix(1);
  return text;
}

// The whitespace-separated words of `line`.
std::vector<std::string_view> Words(std::string_view line) {
  std::vector<std::string_view> words;
  for (std::size_t i = 0; i < line.size();) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

// The credentials on one line of the file; nullopt-like kNone when the line is malformed.
PacsCredentials CredentialsFromWords(std::string_view kind, std::string_view secret) {
  PacsCredentials credentials;
  if (kind == "basic") {
    const std::size_t colon = secret.find(':');
    if (colon == 0 || colon == std::string_view::npos) return credentials;
    credentials.kind = PacsCredentials::Kind::kBasic;
    credentials.user = secret.substr(0, colon);
    credentials.password = secret.substr(colon + 1);
  } else if (kind == "bearer") {
    credentials.kind = PacsCredentials::Kind::kBearer;
    credentials.token = secret;
  }
  return credentials;
}

}  // namespace

PacsCredentials ForwardedCredentials(std::string_view token) {
  constexpr std::size_t kMaxToken = 8192;
  std::size_t end = token.find_last_not_of('=');
  end = end == std::string_view::npos ? 0 : end + 1;
  const bool token_chars = end > 0 && std::all_of(token.begin(), token.begin() + end, [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::string_view("-._~+/").find(c) != std::string_view::npos;
  });
  if (token.size() > kMaxToken || !token_chars) {
    throw InputError(fmt::format("the bearer token is not one a PACS can be sent (RFC 6750: 1 to {} of A-Z a-z 0-9 "
                                 "- . _ ~ + /, then '='s)",
                                 kMaxToken));
  }
  PacsCredentials credentials;
  credentials.kind = PacsCredentials::Kind::kForward;
  credentials.token = std::string(token);
  return credentials;
}

bool IsValidPacsName(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'; });
}

void ValidatePacsConfig(const PacsConfig& config) {
  if (!IsValidPacsName(config.name)) {
    throw InputError("PACS configuration: name must be 1 to 64 characters of A-Z, a-z, 0-9, _ and -");
  }
  if (NormaliseBaseUrl(config.base_url) != config.base_url) {
    throw InputError(fmt::format("PACS '{}': base_url is not in its normal form (see NormaliseBaseUrl)", config.name));
  }
  CheckDuration("connect_timeout", config.connect_timeout, milliseconds(100), milliseconds(60'000));
  CheckDuration("request_timeout", config.request_timeout, milliseconds(100), milliseconds(3'600'000));
  CheckRange<std::uint64_t>("max_response_bytes", config.max_response_bytes, 1024, std::uint64_t{4} << 30);
  CheckRange<std::uint64_t>("max_json_bytes", config.max_json_bytes, 1024, std::uint64_t{256} << 20);
  CheckRange<std::size_t>("max_instances", config.max_instances, 1, 100'000);
  CheckRange<std::uint64_t>("max_series_bytes", config.max_series_bytes, 1024, std::uint64_t{64} << 30);
  CheckRange("parallel_fetches", config.parallel_fetches, 1, 32);
  CheckRange("max_search_results", config.max_search_results, 1, 5000);
  const auto& c = config.credentials;
  if (c.kind == PacsCredentials::Kind::kBasic && c.user.empty()) {
    throw InputError(fmt::format("PACS '{}': basic credentials without a user", config.name));
  }
  if (c.kind == PacsCredentials::Kind::kBearer && c.token.empty()) {
    throw InputError(fmt::format("PACS '{}': bearer credentials without a token", config.name));
  }
}

std::string NormaliseBaseUrl(std::string_view text) {
  // Checked before libcurl sees it: libcurl would quietly encode spaces, and its
  // messages may quote the URL.
  if (text.empty() || text.size() > 2048 || HasControlOrSpace(text) || text.find('\\') != std::string_view::npos) {
    throw InputError("PACS URL must be 1 to 2048 characters without spaces, control characters or backslashes");
  }
  std::unique_ptr<CURLU, decltype(&curl_url_cleanup)> url(curl_url(), curl_url_cleanup);
  if (!url || curl_url_set(url.get(), CURLUPART_URL, std::string(text).c_str(), 0) != CURLUE_OK) {
    throw InputError("PACS URL is not a valid absolute http:// or https:// URL");
  }
  std::string scheme = UrlPart(url.get(), CURLUPART_SCHEME);
  std::transform(scheme.begin(), scheme.end(), scheme.begin(), [](unsigned char c) { return std::tolower(c); });
  if (scheme != "http" && scheme != "https") throw InputError("PACS URL must start with http:// or https://");
  if (!UrlPart(url.get(), CURLUPART_USER).empty() || text.find('@') != std::string_view::npos) {
    throw InputError("PACS URL must not hold user info (user:password@): credentials go in the credentials file");
  }
  if (UrlPart(url.get(), CURLUPART_HOST).empty()) throw InputError("PACS URL has no host");
  if (text.find('?') != std::string_view::npos || text.find('#') != std::string_view::npos) {
    throw InputError("PACS URL must not hold a query (?) or a fragment (#)");
  }
  std::string normal = scheme + std::string(text.substr(text.find(':')));
  while (normal.back() == '/') normal.pop_back();
  return normal;
}

PacsConfig ParsePacsSpec(std::string_view spec) {
  const std::size_t equals = spec.find('=');
  if (equals == std::string_view::npos) throw InputError("--pacs expects NAME=URL");
  PacsConfig config;
  config.name = std::string(spec.substr(0, equals));
  if (!IsValidPacsName(config.name)) {
    throw InputError("--pacs NAME must be 1 to 64 characters of A-Z, a-z, 0-9, _ and -");
  }
  try {
    config.base_url = NormaliseBaseUrl(spec.substr(equals + 1));
  } catch (const InputError& e) {
    throw InputError(fmt::format("--pacs {}: {}", config.name, e.what()));
  }
  return config;
}

std::map<std::string, PacsCredentials> ParseCredentials(std::string_view text, std::string_view source) {
  std::map<std::string, PacsCredentials> credentials;
  std::size_t number = 0;
  for (std::size_t start = 0; start <= text.size(); ++number) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = Trim(text.substr(start, end - start));
    start = end + 1;
    if (line.empty() || line.front() == '#') continue;
    const auto where = fmt::format("{} line {}", source, number + 1);
    const std::vector<std::string_view> words = Words(line);
    if (words.size() != 3) throw InputError(where + ": expected NAME basic USER:PASSWORD or NAME bearer TOKEN");
    if (!IsValidPacsName(words[0])) throw InputError(where + ": the PACS name must be of A-Z, a-z, 0-9, _ and -");
    PacsCredentials entry = CredentialsFromWords(words[1], words[2]);
    if (entry.kind == PacsCredentials::Kind::kNone) {
      throw InputError(where + ": expected NAME basic USER:PASSWORD or NAME bearer TOKEN");
    }
    if (!credentials.emplace(std::string(words[0]), std::move(entry)).second) {
      throw InputError(fmt::format("{}: PACS '{}' has credentials on an earlier line too", where, words[0]));
    }
  }
  return credentials;
}

std::map<std::string, PacsCredentials> LoadCredentialsFile(const std::filesystem::path& path) {
  constexpr std::uintmax_t kMaxBytes = 1 << 20;
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    throw InputError("PACS credentials file is not a regular file: " + path.filename().string());
  }
  if (std::filesystem::file_size(path, error) > kMaxBytes) {
    throw InputError("PACS credentials file is larger than 1 MiB: " + path.filename().string());
  }
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) throw InputError("PACS credentials file cannot be read: " + path.filename().string());
  return ParseCredentials(text.str(), path.filename().string());
}

}  // namespace cinevol::pacs

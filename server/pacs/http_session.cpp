// libcurl with the walls of http_session.h, one handle per session.
#include "pacs/http_session.h"

#include <curl/curl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <mutex>
#include <stdexcept>

#include "core/error.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

void InitialiseCurlOnce() {
  static std::once_flag once;
  std::call_once(once, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
}

// Why a transfer stopped before its end, when it was our doing.
enum class Stop { kNone, kBodyCap, kBudget, kCancelled, kWriteFailed };

struct Transfer {
  const HttpRequest& request;
  HttpResponse& response;
  Stop stop = Stop::kNone;
};

bool IsSet(const std::atomic<bool>* flag) { return flag != nullptr && flag->load(); }

// Writes all of `bytes` to `fd`; false on any error.
bool WriteAll(int fd, const char* data, std::size_t bytes) {
  while (bytes > 0) {
    const ssize_t n = ::write(fd, data, bytes);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n, bytes -= std::size_t(n);
  }
  return true;
}

// libcurl's write callback: the cap and the budget are checked before a byte
// is kept, so an answer never holds more than its cap, in memory or on disk.
std::size_t OnBody(char* data, std::size_t size, std::size_t count, void* user) {
  auto& transfer = *static_cast<Transfer*>(user);
  const std::size_t bytes = size * count;
  HttpResponse& response = transfer.response;
  if (response.body_bytes + bytes > transfer.request.max_body_bytes) {
    transfer.stop = Stop::kBodyCap;
    return 0;  // anything but `bytes` aborts the transfer
  }
  if (transfer.request.budget != nullptr && !transfer.request.budget->Take(bytes)) {
    transfer.stop = Stop::kBudget;
    return 0;
  }
  if (transfer.request.body_fd >= 0) {
    if (!WriteAll(transfer.request.body_fd, data, bytes)) {
      transfer.stop = Stop::kWriteFailed;
      return 0;
    }
  } else {
    response.body.append(data, bytes);
  }
  response.body_bytes += bytes;
  return bytes;
}

// libcurl calls this many times a second while data flow and about once a
// second while they do not, which bounds how long a cancel waits.
int OnProgress(void* user, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
  auto& transfer = *static_cast<Transfer*>(user);
  if (IsSet(transfer.request.cancel) || IsSet(transfer.request.abandon)) {
    transfer.stop = Stop::kCancelled;
    return 1;
  }
  return 0;
}

// The option name of a limit, as the command line will spell it: "pacs-max-response-bytes".
std::string LimitFlag(std::string_view limit_name) {
  std::string flag = "pacs-" + std::string(limit_name);
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

[[noreturn]] void ThrowFailure(const PacsConfig& config, const HttpRequest& request, CURLcode code, Stop stop) {
  const std::string& name = config.name;
  if (stop == Stop::kCancelled) throw Cancelled(fmt::format("PACS '{}': {} cancelled", name, request.what));
  if (stop == Stop::kWriteFailed) {
    throw std::runtime_error(fmt::format("PACS '{}': the answer to {} could not be written to the server's disk", name,
                                         request.what));
  }
  if (stop == Stop::kBudget) {
    throw OverLimit("pacs-max-series-bytes",
                    fmt::format("PACS '{}': {} passed the limit of {} bytes for one series (max_series_bytes)", name,
                                request.what, request.budget->limit()));
  }
  if (stop == Stop::kBodyCap || code == CURLE_FILESIZE_EXCEEDED) {
    throw OverLimit(LimitFlag(request.limit_name),
                    fmt::format("PACS '{}': the answer to {} is larger than the limit of {} bytes ({})", name,
                                request.what, request.max_body_bytes, request.limit_name));
  }
  if (code == CURLE_OPERATION_TIMEDOUT) {
    throw PacsError(fmt::format("PACS '{}' did not answer {} in time (connect_timeout {} ms, request_timeout {} ms)",
                                name, request.what, config.connect_timeout.count(), config.request_timeout.count()));
  }
  if (code == CURLE_COULDNT_CONNECT || code == CURLE_COULDNT_RESOLVE_HOST) {
    throw PacsError(
        fmt::format("PACS '{}' could not be reached for {}: {}", name, request.what, curl_easy_strerror(code)));
  }
  // curl_easy_strerror, not the error buffer: the buffer may quote the URL.
  throw PacsError(fmt::format("PACS '{}': {} failed: {}", name, request.what, curl_easy_strerror(code)));
}

template <class T>
void Set(CURL* curl, CURLoption option, T value) {
  if (curl_easy_setopt(curl, option, value) != CURLE_OK) {
    throw std::runtime_error(fmt::format("libcurl refused option {}", static_cast<int>(option)));
  }
}

struct HeaderList {
  curl_slist* list = nullptr;
  ~HeaderList() { curl_slist_free_all(list); }
  void Add(const std::string& header) {
    curl_slist* longer = curl_slist_append(list, header.c_str());
    if (longer == nullptr) throw std::bad_alloc();
    list = longer;
  }
};

}  // namespace

HttpSession::HttpSession(const PacsConfig& config) : config_(config) {
  InitialiseCurlOnce();
  curl_ = curl_easy_init();
  if (curl_ == nullptr) throw std::runtime_error("libcurl could not make a handle");
}

HttpSession::~HttpSession() { curl_easy_cleanup(static_cast<CURL*>(curl_)); }

void HttpSession::SetCommonOptions() {
  auto* curl = static_cast<CURL*>(curl_);
  Set(curl, CURLOPT_NOSIGNAL, 1L);  // timeouts without SIGALRM: requests run on many threads
  // http and https only, here and after a redirect (which is not followed anyway: a 3xx is the caller's error).
  Set(curl, CURLOPT_PROTOCOLS_STR, "http,https");
  Set(curl, CURLOPT_REDIR_PROTOCOLS_STR, "http,https");
  Set(curl, CURLOPT_FOLLOWLOCATION, 0L);
  Set(curl, CURLOPT_MAXREDIRS, 0L);
  Set(curl, CURLOPT_PROXY, "");  // the configured URL is reached directly, whatever the environment says
  Set(curl, CURLOPT_CONNECTTIMEOUT_MS, static_cast<long>(config_.connect_timeout.count()));
  Set(curl, CURLOPT_TIMEOUT_MS, static_cast<long>(config_.request_timeout.count()));
  Set(curl, CURLOPT_SSL_VERIFYPEER, 1L);
  Set(curl, CURLOPT_SSL_VERIFYHOST, 2L);
  if (!config_.ca_file.empty()) Set(curl, CURLOPT_CAINFO, config_.ca_file.c_str());
  Set(curl, CURLOPT_USERAGENT, "cinevol");
  const PacsCredentials& credentials = config_.credentials;
  if (credentials.kind == PacsCredentials::Kind::kBasic) {
    Set(curl, CURLOPT_HTTPAUTH, static_cast<long>(CURLAUTH_BASIC));
    Set(curl, CURLOPT_USERNAME, credentials.user.c_str());
    Set(curl, CURLOPT_PASSWORD, credentials.password.c_str());
  } else if (credentials.kind == PacsCredentials::Kind::kBearer || credentials.kind == PacsCredentials::Kind::kForward) {
    Set(curl, CURLOPT_HTTPAUTH, static_cast<long>(CURLAUTH_BEARER));
    Set(curl, CURLOPT_XOAUTH2_BEARER, credentials.token.c_str());
  }
}

HttpResponse HttpSession::Perform(const HttpRequest& request) {
  // The last wall against a URL from elsewhere: the client builds every URL from the base URL.
  if (request.url.rfind(config_.base_url + "/", 0) != 0 && request.url != config_.base_url) {
    throw std::logic_error("HttpSession: a URL outside the PACS's base URL");
  }
  auto* curl = static_cast<CURL*>(curl_);
  curl_easy_reset(curl);  // options only: the connections stay for the next request
  SetCommonOptions();
  HttpResponse response;
  Transfer transfer{request, response};
  HeaderList headers;
  for (const std::string& header : request.headers) headers.Add(header);
  headers.Add("Expect:");  // no 100-continue round trip before a store's body
  Set(curl, CURLOPT_URL, request.url.c_str());
  Set(curl, CURLOPT_HTTPHEADER, headers.list);
  if (request.post) {
    Set(curl, CURLOPT_POST, 1L);
    Set(curl, CURLOPT_POSTFIELDS, request.body.data());
    Set(curl, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(request.body.size()));
  }
  Set(curl, CURLOPT_MAXFILESIZE_LARGE, static_cast<curl_off_t>(request.max_body_bytes));
  Set(curl, CURLOPT_WRITEFUNCTION, OnBody);
  Set(curl, CURLOPT_WRITEDATA, &transfer);
  Set(curl, CURLOPT_NOPROGRESS, 0L);
  Set(curl, CURLOPT_XFERINFOFUNCTION, OnProgress);
  Set(curl, CURLOPT_XFERINFODATA, &transfer);
  const CURLcode code = curl_easy_perform(curl);
  if (code != CURLE_OK) ThrowFailure(config_, request, code, transfer.stop);
  curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &response.status);
  const char* content_type = nullptr;
  if (curl_easy_getinfo(curl, CURLINFO_CONTENT_TYPE, &content_type) == CURLE_OK && content_type != nullptr) {
    response.content_type = content_type;
  }
  return response;
}

std::string EscapeUrlComponent(const std::string& text) {
  InitialiseCurlOnce();
  char* escaped = curl_easy_escape(nullptr, text.data(), static_cast<int>(text.size()));
  if (escaped == nullptr) throw std::bad_alloc();
  std::string result(escaped);
  curl_free(escaped);
  return result;
}

}  // namespace cinevol::pacs

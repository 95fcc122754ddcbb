// HTTP to one PACS over libcurl, with the walls every request needs: http and
// https only, no redirects followed, a cap on what an answer may hold enforced
// while it arrives, timeouts, the PACS's credentials, and cancellation.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "pacs/pacs_config.h"

namespace cinevol::pacs {

// Bytes that several transfers may receive together (one series' instances):
// each takes its share as the bytes arrive, and the one that passes the limit
// is aborted.
class ByteBudget {
 public:
  explicit ByteBudget(std::uint64_t limit) : limit_(limit) {}
  // Counts `bytes` more; false once the total is past the limit.
  bool Take(std::uint64_t bytes) { return used_.fetch_add(bytes) + bytes <= limit_; }
  std::uint64_t used() const { return used_.load(); }
  std::uint64_t limit() const { return limit_; }

 private:
  std::atomic<std::uint64_t> used_{0};
  const std::uint64_t limit_;
};

struct HttpRequest {
  // What is asked, for messages ("a search for studies"): never a URL or a patient's data.
  std::string what;
  // Built by the DICOMweb client from the configured base URL; never one from a request.
  std::string url;
  bool post = false;                 // POST `body`, else GET
  std::vector<std::string> headers;  // "Name: value"
  std::string body;
  // The largest answer body accepted; an answer that passes it is aborted (OverLimit naming `limit_name`).
  std::uint64_t max_body_bytes = 0;
  const char* limit_name = "max_response_bytes";
  // Shared with the other transfers of one series, or null.
  ByteBudget* budget = nullptr;
  // Checked while the transfer runs (at least once a second): set, the transfer stops with Cancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Like `cancel`, for the caller's own reasons (another transfer of the same series failed).
  const std::atomic<bool>* abandon = nullptr;
  // An open file the body is written to as it arrives, instead of
  // HttpResponse::body: an instance, which may be large, never sits in memory.
  int body_fd = -1;
};

struct HttpResponse {
  long status = 0;
  std::string content_type;
  std::string body;             // empty when the request gave body_fd
  std::uint64_t body_bytes = 0;  // received, wherever they went
};

// One libcurl handle for one PACS, reused from request to request so that its
// connections are too. Not thread-safe: one per thread.
class HttpSession {
 public:
  explicit HttpSession(const PacsConfig& config);
  ~HttpSession();
  HttpSession(const HttpSession&) = delete;
  HttpSession& operator=(const HttpSession&) = delete;

  // Performs `request` and returns whatever status the PACS answered (checking
  // it is the caller's). Throws PacsError when there is no answer (unreachable,
  // timed out, TLS), OverLimit when the body passes its cap or the budget,
  // Cancelled when `request.cancel` was set, std::runtime_error when the body
  // cannot be written to `request.body_fd`.
  HttpResponse Perform(const HttpRequest& request);

 private:
  void SetCommonOptions();
  const PacsConfig config_;
  void* curl_;  // CURL*, kept out of this header
};

// `text` percent-encoded for one URL path segment or query value.
std::string EscapeUrlComponent(const std::string& text);

}  // namespace cinevol::pacs

// WADO-RS: a series' instances fetched on a bounded number of threads, each
// answer checked to be one DICOM instance before the caller sees its bytes.
#include <fmt/format.h>

#include <algorithm>
#include <exception>
#include <mutex>
#include <thread>

#include "core/error.h"
#include "pacs/dicomweb_client.h"
#include "pacs/dicomweb_requests.h"
#include "pacs/multipart.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

// "As stored": a PACS that transcodes may fail (Orthanc answers 500 for JPEG
// 2000 otherwise) or lose precision; GDCM in the reader cage decodes them all.
constexpr const char* kAcceptInstance = "Accept: multipart/related; type=\"application/dicom\"; transfer-syntax=*";

// The one DICOM instance a WADO-RS answer holds, cut out of its body in place.
std::string SingleInstance(const PacsConfig& config, HttpResponse& response) {
  std::size_t start = 0;
  std::size_t size = 0;
  try {
    const std::string boundary = MultipartBoundary(response.content_type);
    const std::vector<MultipartPart> parts = SplitMultipart(response.body, boundary, 1);
    if (parts.empty()) throw MultipartError("the body has no part");
    const std::string type = PartMediaType(parts.front().headers);
    if (!type.empty() && type != "application/dicom") throw MultipartError("its part is not application/dicom");
    if (!IsPart10(parts.front().body)) throw MultipartError("its part is not a DICOM Part 10 file");
    start = parts.front().body.data() - response.body.data();
    size = parts.front().body.size();
  } catch (const MultipartError& e) {
    throw PacsError(
        fmt::format("PACS '{}' answered a retrieve of an instance with a malformed body: {}", config.name, e.what()),
        response.status);
  }
  response.body.resize(start + size);
  response.body.erase(0, start);
  return std::move(response.body);
}

// Counts the fetches in flight, and the most there were at once.
class InFlight {
 public:
  class Scope {
   public:
    explicit Scope(InFlight& owner) : owner_(owner) {
      const int now = ++owner_.now_;
      int most = owner_.most_.load();
      while (now > most && !owner_.most_.compare_exchange_weak(most, now)) {
      }
    }
    ~Scope() { --owner_.now_; }

   private:
    InFlight& owner_;
  };
  int most() const { return most_.load(); }

 private:
  std::atomic<int> now_{0};
  std::atomic<int> most_{0};
};

class SeriesFetch {
 public:
  SeriesFetch(const PacsConfig& config, std::string series_url, const std::vector<InstanceSummary>& instances,
              const RetrieveCallbacks& callbacks, const std::atomic<bool>* cancel)
      : config_(config),
        series_url_(std::move(series_url)),
        instances_(instances),
        callbacks_(callbacks),
        cancel_(cancel),
        budget_(config.max_series_bytes) {}

  RetrieveStats Run() {
    const int threads = std::min<int>(config_.parallel_fetches, int(instances_.size()));
    std::vector<std::thread> workers;
    for (int i = 0; i < threads; ++i) workers.emplace_back([this] { Work(); });
    for (std::thread& worker : workers) worker.join();
    if (error_) std::rethrow_exception(error_);
    if (Cancelling()) throw Cancelled(fmt::format("PACS '{}': the retrieve of a series was cancelled", config_.name));
    return {done_, budget_.used(), in_flight_.most()};
  }

 private:
  bool Cancelling() const { return cancel_ != nullptr && cancel_->load(); }

  void Work() {
    try {
      HttpSession session(config_);
      for (std::size_t i = next_++; i < instances_.size() && !abandon_ && !Cancelling(); i = next_++) {
        Deliver(instances_[i], Fetch(session, instances_[i]));
      }
    } catch (...) {
      Fail(std::current_exception());
    }
  }

  std::string Fetch(HttpSession& session, const InstanceSummary& instance) {
    HttpRequest request;
    request.what = "a retrieve of an instance";
    request.url = series_url_ + "/instances/" + EscapeUrlComponent(instance.sop_instance_uid);
    request.headers = {kAcceptInstance};
    request.max_body_bytes = config_.max_response_bytes;
    request.budget = &budget_;
    request.cancel = cancel_;
    request.abandon = &abandon_;
    HttpResponse response;
    {
      InFlight::Scope counted(in_flight_);
      response = session.Perform(request);
    }
    CheckStatus(config_, response, request.what, {200});
    return SingleInstance(config_, response);
  }

  // Hands one instance to the caller: one call at a time, none after a failure or a cancel.
  void Deliver(const InstanceSummary& instance, std::string&& bytes) {
    std::lock_guard lock(deliver_mutex_);
    if (abandon_ || Cancelling()) return;
    if (callbacks_.on_instance) callbacks_.on_instance(instance, std::move(bytes));
    ++done_;
    if (callbacks_.on_progress) callbacks_.on_progress(done_, instances_.size());
  }

  // Keeps the first error and stops the other fetches (their transfers abort).
  void Fail(std::exception_ptr error) {
    std::lock_guard lock(error_mutex_);
    if (!error_) error_ = error;
    abandon_ = true;
  }

  const PacsConfig& config_;
  const std::string series_url_;
  const std::vector<InstanceSummary>& instances_;
  const RetrieveCallbacks& callbacks_;
  const std::atomic<bool>* cancel_;
  ByteBudget budget_;
  InFlight in_flight_;
  std::atomic<std::size_t> next_{0};
  std::atomic<bool> abandon_{false};
  std::mutex deliver_mutex_;
  std::size_t done_ = 0;
  std::mutex error_mutex_;
  std::exception_ptr error_;
};

}  // namespace

RetrieveStats DicomWebClient::RetrieveSeries(const std::string& study_uid, const std::string& series_uid,
                                             const RetrieveCallbacks& callbacks,
                                             const std::atomic<bool>* cancel) const {
  const std::string series_url = SeriesUrl(config_, study_uid, series_uid);  // checks both UIDs first
  const std::vector<InstanceSummary> instances = ListInstances(study_uid, series_uid, cancel);
  if (callbacks.on_listing) callbacks.on_listing(instances);
  return SeriesFetch(config_, series_url, instances, callbacks, cancel).Run();
}

}  // namespace cinevol::pacs

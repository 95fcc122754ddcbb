// WADO-RS: a series' instances fetched on a bounded number of threads, each
// answer checked to be one DICOM instance before the caller sees its bytes.
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
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

namespace fs = std::filesystem;

// "As stored": a PACS that transcodes may fail (Orthanc answers 500 for JPEG
// 2000 otherwise) or lose precision; GDCM in the reader cage decodes them all.
constexpr const char* kAcceptInstance = "Accept: multipart/related; type=\"application/dicom\"; transfer-syntax=*";

// A file mapped read-only: its bytes as a view, backed by the page cache, not
// by this process's memory.
class MappedFile {
 public:
  explicit MappedFile(const fs::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    struct stat info {};
    if (fd < 0 || ::fstat(fd, &info) != 0) {
      if (fd >= 0) ::close(fd);
      throw std::runtime_error("cannot read back a retrieved answer from the server's disk");
    }
    size_ = std::size_t(info.st_size);
    if (size_ > 0) data_ = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    ::close(fd);
    if (data_ == MAP_FAILED) throw std::runtime_error("cannot map a retrieved answer");
  }
  ~MappedFile() {
    if (data_ != nullptr && data_ != MAP_FAILED) ::munmap(data_, size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  std::string_view bytes() const { return {static_cast<const char*>(data_), data_ ? size_ : 0}; }

 private:
  void* data_ = nullptr;
  std::size_t size_ = 0;
};

// A file of ours, open for writing, closed when dropped.
struct OutputFile {
  explicit OutputFile(const fs::path& path) : fd(::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600)) {
    if (fd < 0) throw std::runtime_error("cannot write a retrieved instance to the server's disk");
  }
  ~OutputFile() { ::close(fd); }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  int fd;
};

// The one DICOM instance a WADO-RS answer (the multipart body in `answer`)
// holds, written to `instance`; its size in bytes.
std::uint64_t CutOutInstance(const PacsConfig& config, long status, const std::string& content_type,
                             const fs::path& answer, const fs::path& instance) {
  const MappedFile body(answer);
  std::string_view part;
  try {
    const std::string boundary = MultipartBoundary(content_type);
    const std::vector<MultipartPart> parts = SplitMultipart(body.bytes(), boundary, 1);
    if (parts.empty()) throw MultipartError("the body has no part");
    const std::string type = PartMediaType(parts.front().headers);
    if (!type.empty() && type != "application/dicom") throw MultipartError("its part is not application/dicom");
    if (!IsPart10(parts.front().body)) throw MultipartError("its part is not a DICOM Part 10 file");
    part = parts.front().body;
  } catch (const MultipartError& e) {
    throw PacsError(
        fmt::format("PACS '{}' answered a retrieve of an instance with a malformed body: {}", config.name, e.what()),
        status);
  }
  const OutputFile out(instance);
  for (std::size_t done = 0; done < part.size();) {
    const ssize_t n = ::write(out.fd, part.data() + done, part.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error("cannot write a retrieved instance to the server's disk");
    done += std::size_t(n);
  }
  return part.size();
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
              const fs::path& folder, const RetrieveCallbacks& callbacks, const std::atomic<bool>* cancel)
      : config_(config),
        series_url_(std::move(series_url)),
        instances_(instances),
        folder_(folder),
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
        const fs::path file = folder_ / fmt::format("{:06}.dcm", i);
        const std::uint64_t bytes = Fetch(session, instances_[i], file);
        Deliver(instances_[i], file, bytes);
      }
    } catch (...) {
      Fail(std::current_exception());
    }
  }

  // One instance into `file`: the answer streams to a file of its own beside
  // it, from which the instance is cut out.
  std::uint64_t Fetch(HttpSession& session, const InstanceSummary& instance, const fs::path& file) {
    fs::path answer = file;
    answer.replace_extension(".answer");
    struct Removed {
      const fs::path& path;
      ~Removed() {
        std::error_code ec;
        fs::remove(path, ec);
      }
    } removed{answer};
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
      const OutputFile body(answer);
      request.body_fd = body.fd;
      InFlight::Scope counted(in_flight_);
      response = session.Perform(request);
    }
    CheckStatus(config_, response, request.what, {200});
    return CutOutInstance(config_, response.status, response.content_type, answer, file);
  }

  // Hands one instance to the caller: one call at a time, none after a failure or a cancel.
  void Deliver(const InstanceSummary& instance, const fs::path& file, std::uint64_t bytes) {
    std::lock_guard lock(deliver_mutex_);
    if (abandon_ || Cancelling()) return;
    if (callbacks_.on_instance) callbacks_.on_instance(instance, file, bytes);
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
  const fs::path& folder_;
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
                                             const fs::path& folder, const RetrieveCallbacks& callbacks,
                                             const std::atomic<bool>* cancel) const {
  const std::string series_url = SeriesUrl(config_, study_uid, series_uid);  // checks both UIDs first
  const std::vector<InstanceSummary> instances = ListInstances(study_uid, series_uid, cancel);
  if (callbacks.on_listing) callbacks.on_listing(instances);
  return SeriesFetch(config_, series_url, instances, folder, callbacks, cancel).Run();
}

}  // namespace cinevol::pacs

// STOW-RS: instances posted to a study as one multipart/related body, and the
// PACS's answer read for what it stored and what it refused.
#include <fmt/format.h>

#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "core/error.h"
#include "pacs/dicomweb_client.h"
#include "pacs/dicomweb_requests.h"
#include "pacs/multipart.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

constexpr std::size_t kFailuresNamed = 5;

struct StoreAnswer {
  std::vector<std::string> stored;
  std::vector<std::string> failures;  // "SOP-UID: 0xA700 (out of resources)"
};

// PS3.18 Table I.2-3's commonest failure reasons, for messages an operator can act on.
std::string FailureReasonName(std::int64_t reason) {
  switch (reason) {
    case 0x0110:
      return "processing failure";
    case 0x0122:
      return "SOP class not supported";
    case 0x0124:
      return "not authorized";
    case 0xA700:
      return "out of resources";
    case 0xA900:
      return "data set does not match SOP class";
    case 0xC000:
      return "cannot understand";
    case 0xC122:
      return "referenced transfer syntax not supported";
    default:
      return "reason unknown to cinevol";
  }
}

StoreAnswer ReadStoreAnswer(const std::string& body, std::size_t max_items) {
  StoreAnswer answer;
  JsonDocument storage;
  const std::vector<DicomJsonDataset> datasets = TryParseDicomJson(body, storage);
  if (datasets.empty()) return answer;
  const DicomJsonDataset& top = datasets.front();
  for (const DicomJsonDataset& item : top.Items(tag::kReferencedSopSequence, max_items)) {
    answer.stored.push_back(item.Text(tag::kReferencedSopInstanceUid));
  }
  for (const DicomJsonDataset& item : top.Items(tag::kFailedSopSequence, max_items)) {
    const std::optional<std::int64_t> reason = item.Count(tag::kFailureReason);
    std::string uid = item.Text(tag::kReferencedSopInstanceUid);
    if (!IsValidUid(uid)) uid = "(no valid UID)";
    answer.failures.push_back(reason ? fmt::format("{}: {:#06x} ({})", uid, *reason, FailureReasonName(*reason))
                                     : fmt::format("{}: no reason given", uid));
  }
  return answer;
}

std::string NameFailures(const std::vector<std::string>& failures) {
  if (failures.empty()) return "";
  std::string text = "; refused: ";
  for (std::size_t i = 0; i < failures.size() && i < kFailuresNamed; ++i) text += (i ? ", " : "") + failures[i];
  if (failures.size() > kFailuresNamed) text += fmt::format(" and {} more", failures.size() - kFailuresNamed);
  return text;
}

void CheckInstancesToStore(const PacsConfig& config, const std::vector<std::string>& instances) {
  if (instances.empty()) throw InputError("store: no instances to store");
  if (instances.size() > config.max_instances) {
    throw OverLimit("pacs-max-instances", fmt::format("PACS '{}': a store of {} instances is over the limit of {} "
                                                      "(max_instances)",
                                                      config.name, instances.size(), config.max_instances));
  }
  const std::uint64_t bytes = std::accumulate(instances.begin(), instances.end(), std::uint64_t{0},
                                              [](std::uint64_t sum, const std::string& i) { return sum + i.size(); });
  if (bytes > config.max_series_bytes) {
    throw OverLimit("pacs-max-series-bytes", fmt::format("PACS '{}': a store of {} bytes is over the limit of {} "
                                                         "(max_series_bytes)",
                                                         config.name, bytes, config.max_series_bytes));
  }
  for (std::size_t i = 0; i < instances.size(); ++i) {
    if (!IsPart10(instances[i])) throw InputError(fmt::format("store: instance {} is not a DICOM Part 10 file", i));
  }
}

// A boundary that none of `instances` holds (a random one almost never does).
std::string BoundaryFor(const std::vector<std::string>& instances) {
  for (int attempt = 0; attempt < 8; ++attempt) {
    std::string boundary = NewBoundary();
    const bool clashes = std::any_of(instances.begin(), instances.end(), [&](const std::string& instance) {
      return instance.find(boundary) != std::string::npos;
    });
    if (!clashes) return boundary;
  }
  throw std::runtime_error("store: no multipart boundary found that the instances do not hold");
}

}  // namespace

StoreResult DicomWebClient::StoreInstances(const std::string& study_uid, const std::vector<std::string>& instances,
                                           const std::atomic<bool>* cancel) const {
  const std::string url = StudyUrl(config_, study_uid);
  CheckInstancesToStore(config_, instances);
  const std::string boundary = BoundaryFor(instances);
  HttpRequest request;
  request.what = "a store of instances";
  request.url = url;
  request.post = true;
  request.headers = {"Content-Type: multipart/related; type=\"application/dicom\"; boundary=" + boundary,
                     "Accept: application/dicom+json"};
  request.body = JoinMultipart(instances, boundary, "application/dicom");
  request.max_body_bytes = config_.max_json_bytes;
  request.limit_name = "max_json_bytes";
  request.cancel = cancel;
  HttpSession session(config_);
  const HttpResponse response = session.Perform(request);
  // A redirect or a refusal of the credentials is said as for every request; any other status
  // is read for the PACS's report of what it stored and refused.
  const long status = response.status;
  if ((status >= 300 && status < 400) || status == 401 || status == 403) {
    CheckStatus(config_, response, request.what, {200, 202});
  }
  const StoreAnswer answer = ReadStoreAnswer(response.body, instances.size());
  if ((status == 200 || status == 202) && answer.failures.empty()) {
    return {answer.stored};
  }
  throw PacsError(fmt::format("PACS '{}' stored {} of {} instances (HTTP {}){}", config_.name, answer.stored.size(),
                              instances.size(), status, NameFailures(answer.failures)),
                  status);
}

}  // namespace cinevol::pacs

// URLs, statuses and DICOM JSON: the parts of every DICOMweb request.
#include "pacs/dicomweb_requests.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "core/error.h"
#include "pacs/dicomweb_client.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {

void CheckUid(const std::string& uid, const char* field) {
  if (!IsValidUid(uid)) throw InputError(fmt::format("{} is not a DICOM UID (1 to 64 digits and dots)", field));
}

std::string StudyUrl(const PacsConfig& config, const std::string& study_uid) {
  CheckUid(study_uid, "study_uid");
  return config.base_url + "/studies/" + EscapeUrlComponent(study_uid);
}

std::string SeriesUrl(const PacsConfig& config, const std::string& study_uid, const std::string& series_uid) {
  CheckUid(series_uid, "series_uid");
  return StudyUrl(config, study_uid) + "/series/" + EscapeUrlComponent(series_uid);
}

void CheckStatus(const PacsConfig& config, const HttpResponse& response, const std::string& what,
                 std::initializer_list<long> accepted) {
  const long status = response.status;
  if (std::find(accepted.begin(), accepted.end(), status) != accepted.end()) return;
  const std::string& name = config.name;
  if (status >= 300 && status < 400) {
    throw PacsError(fmt::format("PACS '{}' answered {} with HTTP {}, a redirect, which cinevol does not follow: "
                                "configure the PACS's URL as it should be reached",
                                name, what, status),
                    status);
  }
  if ((status == 401 || status == 403) && config.credentials.kind == PacsCredentials::Kind::kForward) {
    throw PacsError(fmt::format("PACS '{}' refused the caller's token for {} (HTTP {}; --pacs-auth forward sends "
                                "it as given)",
                                name, what, status),
                    status);
  }
  if (status == 401 || status == 403) {
    throw PacsError(fmt::format("PACS '{}' refused cinevol's credentials for {} (HTTP {}): check its entry in the "
                                "credentials file",
                                name, what, status),
                    status);
  }
  if (status == 404) {
    throw PacsError(fmt::format("PACS '{}' does not have what {} asked for (HTTP 404)", name, what), status);
  }
  throw PacsError(fmt::format("PACS '{}' answered {} with HTTP {}", name, what, status), status);
}

std::vector<DicomJsonDataset> FetchDicomJson(const PacsConfig& config, const std::string& what, const std::string& url,
                                             const std::atomic<bool>* cancel, JsonDocument& storage) {
  HttpRequest request;
  request.what = what;
  request.url = url;
  request.headers = {"Accept: application/dicom+json"};
  request.max_body_bytes = config.max_json_bytes;
  request.limit_name = "max_json_bytes";
  request.cancel = cancel;
  HttpSession session(config);
  const HttpResponse response = session.Perform(request);
  CheckStatus(config, response, what, {200, 204});
  if (response.status == 204 || response.body.empty()) return {};
  try {
    return ParseDicomJson(response.body, storage, cancel);
  } catch (const JsonError& e) {
    throw PacsError(fmt::format("PACS '{}' answered {} with what is not DICOM JSON: {}", config.name, what, e.what()),
                    response.status);
  }
}

std::vector<DicomJsonDataset> TryParseDicomJson(const std::string& body, JsonDocument& storage) {
  try {
    return ParseDicomJson(body, storage);
  } catch (const JsonError&) {
    return {};
  }
}

bool IsPart10(std::string_view bytes) { return bytes.size() >= 132 && bytes.substr(128, 4) == "DICM"; }

}  // namespace cinevol::pacs

// QIDO-RS: searching a PACS's studies, a study's series, a series' instances.
#include "pacs/dicomweb_client.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <set>

#include "core/error.h"
#include "pacs/dicomweb_requests.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

constexpr std::size_t kMaxQueryText = 64;
constexpr int kMaxOffset = 1'000'000;
constexpr std::size_t kMaxModalities = 16;

// Attributes asked for beyond a PACS's defaults (PS3.18 does not require them all in an answer).
// Beyond a study's required matching keys: what a study list shows, and what a
// render sent back into the study copies (secondary_capture.h's SourceStudy).
constexpr const char* kStudyFields[] = {"00081030", "00080061", "00201206", "00201208", "00080050",
                                        "00080030", "00080090", "00100030", "00100040", "00200010"};
constexpr const char* kSeriesFields[] = {"0008103E", "00200011", "00201209", "00080060"};
constexpr const char* kInstanceFields[] = {"00200013", "00280010", "00280011", "00280100", "00280008"};

void CheckQueryText(const std::string& value, const char* field) {
  const bool bad_character = std::any_of(value.begin(), value.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u < 0x20 || u == 0x7f || c == '\\';  // a backslash separates DICOM values
  });
  if (value.size() > kMaxQueryText || bad_character) {
    throw InputError(
        fmt::format("study search: {} must be at most 64 characters without control characters or "
                    "backslashes",
                    field));
  }
}

void CheckDate(const std::string& date, const char* field) {
  const bool digits =
      std::all_of(date.begin(), date.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
  if (!date.empty() && (date.size() != 8 || !digits)) {
    throw InputError(fmt::format("study search: {} must be a date written YYYYMMDD", field));
  }
}

void CheckModality(const std::string& modality) {
  const bool valid = std::all_of(modality.begin(), modality.end(), [](char c) {
    return std::isupper(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) || c == '_';
  });
  if (modality.size() > 16 || !valid) {
    throw InputError("study search: modality must be 1 to 16 of A-Z, 0-9 and _ (e.g. CT, MR)");
  }
}

void CheckStudyQuery(const StudyQuery& query) {
  if (!query.study_uid.empty()) CheckUid(query.study_uid, "study_uid");
  CheckQueryText(query.patient_name, "patient_name");
  CheckQueryText(query.patient_id, "patient_id");
  CheckQueryText(query.accession_number, "accession_number");
  CheckQueryText(query.study_description, "study_description");
  CheckDate(query.study_date_from, "study_date_from");
  CheckDate(query.study_date_to, "study_date_to");
  if (!query.study_date_from.empty() && !query.study_date_to.empty() && query.study_date_from > query.study_date_to) {
    throw InputError("study search: study_date_from is after study_date_to");
  }
  CheckModality(query.modality);
  if (query.limit < 1) throw InputError("study search: limit must be at least 1");
  if (query.offset < 0 || query.offset > kMaxOffset) throw InputError("study search: offset must be in [0; 1000000]");
}

// `value` percent-encoded for a query, but for DICOM's matching characters (`*` `?`), the PN
// component separator `^` and the list separator `,`, which go as they are: Orthanc (1.10)
// does not percent-decode query values, so "DOE%5EJ%2A" would match nothing there, and
// these characters cannot end a value or start another (`&`, `=`, `#`, `+`, `%` are encoded).
std::string EscapeQueryValue(const std::string& value) {
  std::string escaped;
  for (const char c : value) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x80 && (std::isalnum(u) || std::string_view("-._~*?^,").find(c) != std::string_view::npos)) {
      escaped += c;
    } else {
      escaped += fmt::format("%{:02X}", u);
    }
  }
  return escaped;
}

// Appends `key=value` to a query string, the value escaped; empty values are left out.
void AddParameter(std::string& query, const char* key, const std::string& value) {
  if (value.empty()) return;
  query += query.empty() ? "?" : "&";
  query += key;
  query += '=';
  query += EscapeQueryValue(value);
}

template <std::size_t N>
void AddIncludeFields(std::string& query, const char* const (&fields)[N]) {
  for (const char* field : fields) AddParameter(query, "includefield", field);
}

std::string StudySearchQuery(const StudyQuery& query, int limit) {
  std::string text;
  AddParameter(text, "StudyInstanceUID", query.study_uid);
  AddParameter(text, "PatientName", query.patient_name);
  AddParameter(text, "PatientID", query.patient_id);
  if (!query.study_date_from.empty() || !query.study_date_to.empty()) {
    AddParameter(text, "StudyDate", query.study_date_from + "-" + query.study_date_to);
  }
  AddParameter(text, "ModalitiesInStudy", query.modality);
  AddParameter(text, "AccessionNumber", query.accession_number);
  AddParameter(text, "StudyDescription", query.study_description);
  AddParameter(text, "limit", std::to_string(limit));
  AddParameter(text, "offset", query.offset > 0 ? std::to_string(query.offset) : "");
  AddIncludeFields(text, kStudyFields);
  return text;
}

StudySummary StudyFrom(const DicomJsonDataset& dataset) {
  StudySummary study;
  study.study_uid = dataset.Text(tag::kStudyInstanceUid);
  study.patient_name = dataset.PersonName(tag::kPatientName);
  study.patient_id = dataset.Text(tag::kPatientId);
  study.study_date = dataset.Text(tag::kStudyDate);
  study.description = dataset.Text(tag::kStudyDescription);
  study.accession_number = dataset.Text(tag::kAccessionNumber);
  study.modalities = dataset.Texts(tag::kModalitiesInStudy, kMaxModalities);
  study.series_count = dataset.Count(tag::kNumberOfStudyRelatedSeries);
  study.instance_count = dataset.Count(tag::kNumberOfStudyRelatedInstances);
  study.study_time = dataset.Text(tag::kStudyTime);
  study.study_id = dataset.Text(tag::kStudyId);
  study.referring_physician = dataset.PersonName(tag::kReferringPhysicianName);
  study.patient_birth_date = dataset.Text(tag::kPatientBirthDate);
  study.patient_sex = dataset.Text(tag::kPatientSex);
  return study;
}

SeriesSummary SeriesFrom(const DicomJsonDataset& dataset) {
  SeriesSummary series;
  series.series_uid = dataset.Text(tag::kSeriesInstanceUid);
  series.modality = dataset.Text(tag::kModality);
  series.description = dataset.Text(tag::kSeriesDescription);
  series.series_number = dataset.Count(tag::kSeriesNumber);
  series.instance_count = dataset.Count(tag::kNumberOfSeriesRelatedInstances);
  return series;
}

InstanceSummary InstanceFrom(const DicomJsonDataset& dataset) {
  InstanceSummary instance;
  instance.sop_instance_uid = dataset.Text(tag::kSopInstanceUid);
  instance.instance_number = dataset.Count(tag::kInstanceNumber);
  instance.rows = dataset.Count(tag::kRows);
  instance.columns = dataset.Count(tag::kColumns);
  instance.bits_allocated = dataset.Count(tag::kBitsAllocated);
  instance.frames = dataset.Count(tag::kNumberOfFrames);
  return instance;
}

}  // namespace

DicomWebClient::DicomWebClient(PacsConfig config) : config_(std::move(config)) { ValidatePacsConfig(config_); }

std::vector<StudySummary> DicomWebClient::SearchStudies(const StudyQuery& query,
                                                        const std::atomic<bool>* cancel) const {
  CheckStudyQuery(query);
  const int limit = std::min(query.limit, config_.max_search_results);
  JsonDocument storage;
  const auto datasets = FetchDicomJson(config_, "a search for studies",
                                       config_.base_url + "/studies" + StudySearchQuery(query, limit), cancel, storage);
  std::vector<StudySummary> studies;
  for (const DicomJsonDataset& dataset : datasets) {
    if (studies.size() == std::size_t(limit)) break;  // a PACS that ignores the limit gets cut off here
    StudySummary study = StudyFrom(dataset);
    if (IsValidUid(study.study_uid)) studies.push_back(std::move(study));  // without a UID it cannot be opened
  }
  return studies;
}

std::vector<SeriesSummary> DicomWebClient::SearchSeries(const std::string& study_uid,
                                                        const std::atomic<bool>* cancel) const {
  std::string query;
  AddParameter(query, "limit", std::to_string(config_.max_search_results));
  AddIncludeFields(query, kSeriesFields);
  JsonDocument storage;
  const auto datasets = FetchDicomJson(config_, "a search for a study's series",
                                       StudyUrl(config_, study_uid) + "/series" + query, cancel, storage);
  std::vector<SeriesSummary> series;
  for (const DicomJsonDataset& dataset : datasets) {
    if (series.size() == std::size_t(config_.max_search_results)) break;
    SeriesSummary one = SeriesFrom(dataset);
    if (IsValidUid(one.series_uid)) series.push_back(std::move(one));
  }
  return series;
}

std::vector<InstanceSummary> DicomWebClient::ListInstances(const std::string& study_uid, const std::string& series_uid,
                                                           const std::atomic<bool>* cancel) const {
  std::string query;
  // One more than the limit: enough to know the series is past it without listing all of a huge one.
  AddParameter(query, "limit", std::to_string(config_.max_instances + 1));
  AddIncludeFields(query, kInstanceFields);
  const std::string what = "a listing of a series' instances";
  JsonDocument storage;
  const auto datasets =
      FetchDicomJson(config_, what, SeriesUrl(config_, study_uid, series_uid) + "/instances" + query, cancel, storage);
  std::vector<InstanceSummary> instances;
  std::set<std::string> seen;
  for (const DicomJsonDataset& dataset : datasets) {
    InstanceSummary instance = InstanceFrom(dataset);
    if (!IsValidUid(instance.sop_instance_uid)) {
      throw PacsError(fmt::format("PACS '{}' answered {} with an instance whose SOP Instance UID is not a UID",
                                  config_.name, what));
    }
    if (!seen.insert(instance.sop_instance_uid).second) continue;  // listed twice, fetched once
    if (instances.size() == config_.max_instances) {
      throw OverLimit("pacs-max-instances",
                      fmt::format("PACS '{}': the series has more than {} instances, the limit (max_instances)",
                                  config_.name, config_.max_instances));
    }
    instances.push_back(std::move(instance));
  }
  if (instances.empty()) {
    throw PacsError(fmt::format("PACS '{}' lists no instances for the series asked for (HTTP 404 or an empty "
                                "answer): is the study or series UID right?",
                                config_.name),
                    404);
  }
  return instances;
}

}  // namespace cinevol::pacs

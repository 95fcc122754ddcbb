// What the DICOMweb client's three services share: URLs built from the base
// URL and checked UIDs, HTTP statuses turned into errors, DICOM JSON fetched
// under its cap. Internal to server/pacs.
#pragma once


#include <atomic>
#include <initializer_list>
#include <string>
#include <vector>

#include "pacs/dicom_json.h"
#include "pacs/http_session.h"
#include "pacs/pacs_config.h"

namespace cinevol::pacs {

// DICOM tags the client reads, as (group << 16) | element.
namespace tag {
constexpr std::uint32_t kSpecificCharacterSet = 0x00080005;
constexpr std::uint32_t kSopInstanceUid = 0x00080018;
constexpr std::uint32_t kStudyDate = 0x00080020;
constexpr std::uint32_t kAccessionNumber = 0x00080050;
constexpr std::uint32_t kModality = 0x00080060;
constexpr std::uint32_t kModalitiesInStudy = 0x00080061;
constexpr std::uint32_t kStudyDescription = 0x00081030;
constexpr std::uint32_t kSeriesDescription = 0x0008103E;
constexpr std::uint32_t kReferencedSopInstanceUid = 0x00081155;
constexpr std::uint32_t kFailureReason = 0x00081197;
constexpr std::uint32_t kFailedSopSequence = 0x00081198;
constexpr std::uint32_t kReferencedSopSequence = 0x00081199;
constexpr std::uint32_t kStudyTime = 0x00080030;
constexpr std::uint32_t kReferringPhysicianName = 0x00080090;
constexpr std::uint32_t kPatientName = 0x00100010;
constexpr std::uint32_t kPatientId = 0x00100020;
constexpr std::uint32_t kPatientBirthDate = 0x00100030;
constexpr std::uint32_t kPatientSex = 0x00100040;
constexpr std::uint32_t kStudyId = 0x00200010;
constexpr std::uint32_t kStudyInstanceUid = 0x0020000D;
constexpr std::uint32_t kSeriesInstanceUid = 0x0020000E;
constexpr std::uint32_t kSeriesNumber = 0x00200011;
constexpr std::uint32_t kInstanceNumber = 0x00200013;
constexpr std::uint32_t kNumberOfStudyRelatedSeries = 0x00201206;
constexpr std::uint32_t kNumberOfStudyRelatedInstances = 0x00201208;
constexpr std::uint32_t kNumberOfSeriesRelatedInstances = 0x00201209;
constexpr std::uint32_t kNumberOfFrames = 0x00280008;
constexpr std::uint32_t kRows = 0x00280010;
constexpr std::uint32_t kColumns = 0x00280011;
constexpr std::uint32_t kBitsAllocated = 0x00280100;
}  // namespace tag

// base_url + "/studies/{study}", the UID checked and escaped.
std::string StudyUrl(const PacsConfig& config, const std::string& study_uid);
// base_url + "/studies/{study}/series/{series}".
std::string SeriesUrl(const PacsConfig& config, const std::string& study_uid, const std::string& series_uid);

// Throws PacsError unless `response.status` is one of `accepted`; a redirect, a
// refusal of the credentials and a missing resource each say so.
void CheckStatus(const PacsConfig& config, const HttpResponse& response, const std::string& what,
                 std::initializer_list<long> accepted);

// GETs `url` asking for DICOM JSON (at most max_json_bytes), checks the status
// (200, or 204 for nothing) and parses the answer into `storage`.
std::vector<DicomJsonDataset> FetchDicomJson(const PacsConfig& config, const std::string& what, const std::string& url,
                                             const std::atomic<bool>* cancel, JsonDocument& storage);

// The parsed DICOM JSON of a body that should hold it, or nothing where it does
// not (a PACS may answer an error with HTML).
std::vector<DicomJsonDataset> TryParseDicomJson(const std::string& body, JsonDocument& storage);

// True when `bytes` look like a DICOM Part 10 file: a 128-byte preamble, then "DICM".
bool IsPart10(std::string_view bytes);

}  // namespace cinevol::pacs

#include "pacs/dcmtk_writing.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcostrmb.h>
#include <dcmtk/oflog/oflog.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "core/error.h"
#include "pacs/dicom_json.h"

namespace cinevol::pacs {
namespace {

// Characters, not bytes: the VRs' limits count characters.
std::size_t CharacterCount(std::string_view utf8) {
  return std::size_t(std::count_if(utf8.begin(), utf8.end(), [](char c) { return (c & 0xC0) != 0x80; }));
}

}  // namespace

void Refuse(std::string_view field, std::string_view why) { throw InputError(fmt::format("{} {}", field, why)); }

void Require(const OFCondition& condition, std::string_view document, std::string_view what) {
  if (condition.bad()) throw std::runtime_error(fmt::format("{}: {}: {}", document, what, condition.text()));
}

void QuietDcmtk() {
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::ERROR_LOG_LEVEL); });
}

std::string WithoutTrailingSpaces(std::string text) {
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  return text;
}

bool IsAscii(std::string_view text) {
  return std::all_of(text.begin(), text.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; });
}

void SetChecked(const std::string& field, const std::string& value, std::size_t max_characters, bool person_name,
                const std::function<OFCondition(const OFString&, OFBool)>& set) {
  const std::string clean = WithoutTrailingSpaces(value);
  if (CleanText(clean, clean.size() + 1) != clean) Refuse(field, "is not valid UTF-8");
  if (std::any_of(clean.begin(), clean.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; })) {
    Refuse(field, "holds a control character");
  }
  std::size_t start = 0;
  for (std::size_t groups = 0; start <= clean.size(); ++groups) {
    const std::size_t end = person_name ? std::min(clean.find('=', start), clean.size()) : clean.size();
    const std::size_t characters = CharacterCount(std::string_view(clean).substr(start, end - start));
    if (characters > max_characters || groups == 3) {
      Refuse(field, fmt::format("is longer than its VR allows ({} characters{})", max_characters,
                                person_name ? " in each of at most 3 groups" : ""));
    }
    start = end + 1;
  }
  const OFCondition done = set(clean.c_str(), OFTrue);
  if (done.bad()) Refuse(field, fmt::format("is not what its VR allows ({})", done.text()));
}

DicomNow CurrentDateTime() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm local{};
  localtime_r(&t, &local);
  char date[16], time[16];
  std::strftime(date, sizeof date, "%Y%m%d", &local);
  std::strftime(time, sizeof time, "%H%M%S", &local);
  return {date, time};
}

void PutText(DcmItem& item, const DcmTagKey& tag, const std::string& field, const std::string& value,
             std::size_t max_characters, bool person_name) {
  SetChecked(field, value, max_characters, person_name, [&](const OFString& v, OFBool) {
    OFCondition put = item.putAndInsertOFStringArray(tag, v);
    DcmElement* element = nullptr;
    if (put.good()) put = item.findAndGetElement(tag, element);
    return put.good() ? element->checkValue("1") : put;
  });
}

void PutStudyAttributes(DcmItem& item, const SourceStudy& study) {
  const auto put = [&](const char* field, const std::string& value, std::size_t max_characters, const DcmTagKey& tag,
                       bool person_name = false) {
    PutText(item, tag, std::string("source.") + field, value, max_characters, person_name);
  };
  put("patient_name", study.patient_name, 64, DCM_PatientName, true);  // PN: 64 a group
  put("patient_id", study.patient_id, 64, DCM_PatientID);              // LO
  put("patient_birth_date", study.patient_birth_date, 8, DCM_PatientBirthDate);
  put("patient_sex", study.patient_sex, 16, DCM_PatientSex);
  put("study_id", study.study_id, 16, DCM_StudyID);  // SH
  put("study_date", study.study_date, 8, DCM_StudyDate);
  put("study_time", study.study_time, 16, DCM_StudyTime);
  put("accession_number", study.accession_number, 16, DCM_AccessionNumber);
  put("referring_physician", study.referring_physician, 64, DCM_ReferringPhysicianName, true);
  put("study_description", study.study_description, 64, DCM_StudyDescription);
}

std::string ToPart10(DcmFileFormat& file, std::string_view document, E_TransferSyntax syntax) {
  std::string out;
  std::vector<char> buffer(std::size_t{1} << 20);
  DcmOutputBufferStream stream(buffer.data(), offile_off_t(buffer.size()));
  file.transferInit();
  OFCondition written = EC_StreamNotifyClient;
  while (written == EC_StreamNotifyClient) {
    written = file.write(stream, syntax, EET_ExplicitLength, nullptr, EGL_recalcGL,
                         EPD_withoutPadding, 0, 0, 0, EWM_createNewMeta);
    void* data = nullptr;
    offile_off_t length = 0;
    stream.flushBuffer(data, length);
    out.append(static_cast<const char*>(data), std::size_t(length));
  }
  file.transferEnd();
  Require(written, document, "encoding");
  return out;
}

}  // namespace cinevol::pacs

// A render as a DICOM Secondary Capture, written with GDCM, and the recipe read back out of one.
#include "pacs/secondary_capture.h"

#include <fmt/format.h>
#include <gdcmDataSet.h>
#include <gdcmWriter.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <chrono>
#include <ctime>
#include <map>
#include <random>
#include <sstream>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "pacs/dicom_json.h"

namespace cinevol::pacs {
namespace {

using google::protobuf::Struct;
using google::protobuf::Value;

// Scenes nest a few levels; 32 stays far inside protobuf's own recursion limit (dicom_json.h says why it matters).
constexpr int kMaxRecipeDepth = 32;
constexpr std::size_t kMaxPresetCharacters = 64;
constexpr std::size_t kMaxVersionCharacters = 64;
constexpr std::string_view kDescriptionPrefix = "cinevol render";
constexpr std::size_t kLoCharacters = 64;
// A recipe is its scene and three short fields: the series UID, the version and the preset, quoted.
constexpr std::size_t kMaxRecipeBytes = kMaxSceneJsonBytes + 4096;

[[noreturn]] void Refuse(std::string_view field, std::string_view why) {
  throw InputError(fmt::format("{} {}", field, why));
}

// ---- Text as DICOM's VRs allow it (PS3.5 6.2) ----

// DICOM pads values with spaces; a value from a PACS may keep them.
std::string WithoutTrailingSpaces(std::string text) {
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  return text;
}

// The length of the UTF-8 sequence that `lead` opens; 0 for a byte that opens none.
std::size_t SequenceLength(unsigned char lead) {
  if (lead < 0x80) return 1;
  if ((lead >> 5) == 0x6) return 2;
  if ((lead >> 4) == 0xe) return 3;
  return (lead >> 3) == 0x1e ? 4 : 0;
}

bool IsValidUtf8(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t length = SequenceLength(static_cast<unsigned char>(text[i]));
    if (length == 0 || i + length > text.size()) return false;
    for (std::size_t k = 1; k < length; ++k) {
      if ((static_cast<unsigned char>(text[i + k]) & 0xc0) != 0x80) return false;
    }
    i += length;
  }
  return true;
}

// Characters, not bytes: the VRs' limits count characters.
std::size_t CharacterCount(std::string_view utf8) {
  std::size_t count = 0;
  for (char c : utf8) count += (static_cast<unsigned char>(c) & 0xc0) != 0x80;
  return count;
}

// The first `characters` characters of valid UTF-8 `text`.
std::string CutToCharacters(std::string_view text, std::size_t characters) {
  std::size_t end = 0;
  for (std::size_t seen = 0; end < text.size(); ++end) {
    if ((static_cast<unsigned char>(text[end]) & 0xc0) != 0x80 && seen++ == characters) break;
  }
  return std::string(text.substr(0, end));
}

bool IsAscii(std::string_view text) {
  for (char c : text) {
    if (static_cast<unsigned char>(c) >= 0x80) return false;
  }
  return true;
}

// A value of a single-line text VR (LO, SH, PN): UTF-8, no control characters, and no backslash, which would
// split it into several values.
void CheckLine(std::string_view field, std::string_view value, std::size_t max_characters, std::string_view kind) {
  if (!IsValidUtf8(value)) Refuse(field, "is not valid UTF-8");
  for (char c : value) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) Refuse(field, "holds a control character");
    if (c == '\\') Refuse(field, "holds a backslash, which DICOM reads as a second value");
  }
  const std::size_t characters = CharacterCount(value);
  if (characters > max_characters) {
    Refuse(field, fmt::format("is {} characters; {} allows at most {}", characters, kind, max_characters));
  }
}

// PN: up to three component groups (alphabetic, ideographic, phonetic) of 64 characters each.
void CheckPersonName(std::string_view field, std::string_view value) {
  CheckLine(field, value, 3 * kLoCharacters + 2, "PN");
  std::size_t groups = 0;
  for (std::size_t start = 0; start <= value.size(); ++groups) {
    const std::size_t end = std::min(value.find('=', start), value.size());
    if (CharacterCount(value.substr(start, end - start)) > kLoCharacters) {
      Refuse(field, fmt::format("has a name group over the {} characters PN allows", kLoCharacters));
    }
    start = end + 1;
  }
  if (groups > 3) Refuse(field, "has more than the 3 name groups PN allows");
}

bool AllOf(std::string_view text, std::string_view allowed) {
  return text.find_first_not_of(allowed) == std::string_view::npos;
}

constexpr std::string_view kDigits = "0123456789";

void CheckDate(std::string_view field, std::string_view value) {
  if (!value.empty() && (value.size() != 8 || !AllOf(value, kDigits))) Refuse(field, "is not a DA date (YYYYMMDD)");
}

void CheckTime(std::string_view field, std::string_view value) {
  if (value.size() > 16 || !AllOf(value, "0123456789.") || (!value.empty() && value.front() == '.')) {
    Refuse(field, "is not a TM time (HHMMSS.FFFFFF)");
  }
}

void CheckCodeString(std::string_view field, std::string_view value) {
  if (value.size() > 16 || !AllOf(value, "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _")) {
    Refuse(field, "is not a CS code string (16 of A-Z, 0-9, space, _)");
  }
}

void CheckUidField(std::string_view field, const std::string& value) {
  if (!IsValidUid(value)) Refuse(field, "is not a DICOM UID (1 to 64 digits and dots)");
}

// ---- Inputs ----

SourceStudy CheckedSource(const SourceStudy& given) {
  SourceStudy source;
  source.patient_name = WithoutTrailingSpaces(given.patient_name);
  CheckPersonName("source.patient_name", source.patient_name);
  source.patient_id = WithoutTrailingSpaces(given.patient_id);
  CheckLine("source.patient_id", source.patient_id, kLoCharacters, "LO");
  source.patient_birth_date = WithoutTrailingSpaces(given.patient_birth_date);
  CheckDate("source.patient_birth_date", source.patient_birth_date);
  source.patient_sex = WithoutTrailingSpaces(given.patient_sex);
  CheckCodeString("source.patient_sex", source.patient_sex);
  source.study_uid = WithoutTrailingSpaces(given.study_uid);
  CheckUidField("source.study_uid", source.study_uid);
  source.study_id = WithoutTrailingSpaces(given.study_id);
  CheckLine("source.study_id", source.study_id, 16, "SH");
  source.study_date = WithoutTrailingSpaces(given.study_date);
  CheckDate("source.study_date", source.study_date);
  source.study_time = WithoutTrailingSpaces(given.study_time);
  CheckTime("source.study_time", source.study_time);
  source.accession_number = WithoutTrailingSpaces(given.accession_number);
  CheckLine("source.accession_number", source.accession_number, 16, "SH");
  source.referring_physician = WithoutTrailingSpaces(given.referring_physician);
  CheckPersonName("source.referring_physician", source.referring_physician);
  source.study_description = WithoutTrailingSpaces(given.study_description);
  CheckLine("source.study_description", source.study_description, kLoCharacters, "LO");
  source.series_uid = WithoutTrailingSpaces(given.series_uid);
  if (!source.series_uid.empty()) CheckUidField("source.series_uid", source.series_uid);
  return source;
}

void CheckImage(const SecondaryCaptureImage& image) {
  if (image.width < 1 || image.width > kMaxCaptureSide) {
    Refuse("image.width", fmt::format("is {}; a capture is 1 to {} pixels wide", image.width, kMaxCaptureSide));
  }
  if (image.height < 1 || image.height > kMaxCaptureSide) {
    Refuse("image.height", fmt::format("is {}; a capture is 1 to {} pixels high", image.height, kMaxCaptureSide));
  }
  const std::size_t expected = std::size_t(image.width) * std::size_t(image.height) * 3;
  if (image.rgb.size() != expected) {
    Refuse("image.rgb",
           fmt::format("holds {} bytes; {} x {} RGB is {}", image.rgb.size(), image.width, image.height, expected));
  }
}

// Parses `json` as one JSON object into `value`; false when it is not one, or nests too deep to parse safely.
// JsonDocument checks it first within its bounds, so protobuf's more lenient parser sees only strict JSON.
bool ParseJsonObject(const std::string& json, Value& value) {
  try {
    if (!JsonDocument::Parse(json, {.max_depth = kMaxRecipeDepth}).root().is(JsonDocument::Kind::kObject)) return false;
  } catch (const JsonError&) {
    return false;
  }
  return google::protobuf::util::JsonStringToMessage(json, &value).ok() && value.has_struct_value();
}

// The recipe as checked: the source series it renders, and the rest of it.
struct CheckedRecipe {
  std::string source_series_uid;
  std::string version;
  std::string preset;
};

CheckedRecipe CheckRecipe(const RenderRecipe& recipe, const SourceStudy& source) {
  if (recipe.scene_json.size() > kMaxSceneJsonBytes) {
    Refuse("recipe.scene_json", fmt::format("is {} bytes; at most {}", recipe.scene_json.size(), kMaxSceneJsonBytes));
  }
  Value scene;
  if (!ParseJsonObject(recipe.scene_json, scene)) {
    Refuse("recipe.scene_json", fmt::format("is not one JSON object nesting at most {} levels", kMaxRecipeDepth));
  }
  CheckedRecipe checked{WithoutTrailingSpaces(recipe.source_series_uid), recipe.cinevol_version, recipe.preset};
  if (checked.source_series_uid.empty()) checked.source_series_uid = source.series_uid;
  if (checked.source_series_uid.empty()) Refuse("recipe.source_series_uid", "is empty, and so is source.series_uid");
  CheckUidField("recipe.source_series_uid", checked.source_series_uid);
  if (!source.series_uid.empty() && source.series_uid != checked.source_series_uid) {
    Refuse("recipe.source_series_uid", "differs from source.series_uid");
  }
  if (checked.version.empty() || checked.version.size() > kMaxVersionCharacters ||
      !AllOf(checked.version, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789.+-_")) {
    Refuse("recipe.cinevol_version", "is not 1 to 64 of A-Z a-z 0-9 . + - _");
  }
  CheckLine("recipe.preset", checked.preset, kMaxPresetCharacters, "a preset");
  return checked;
}

// ---- The recipe as JSON ----

std::string JsonQuoted(std::string_view text) {
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      quoted += '\\';
      quoted += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      quoted += fmt::format("\\u{:04x}", int(c));
    } else {
      quoted += c;
    }
  }
  return quoted + "\"";
}

// Written by hand rather than through protobuf so that the scene stays byte for byte as the caller wrote it.
std::string RecipeJson(const std::string& scene_json, const CheckedRecipe& recipe) {
  return "{\"scene\":" + scene_json + ",\"sourceSeriesUid\":" + JsonQuoted(recipe.source_series_uid) +
         ",\"cinevolVersion\":" + JsonQuoted(recipe.version) + ",\"preset\":" + JsonQuoted(recipe.preset) + "}";
}

// ---- Writing ----

struct Timestamp {
  std::string date;    // DA
  std::string time;    // TM
  std::string offset;  // "+HHMM", for Timezone Offset From UTC
};

// Local time, as DICOM dates and times are.
Timestamp Now() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm local{};
  localtime_r(&now, &local);
  char date[16], time[16], offset[16];
  std::strftime(date, sizeof date, "%Y%m%d", &local);
  std::strftime(time, sizeof time, "%H%M%S", &local);
  std::strftime(offset, sizeof offset, "%z", &local);
  return {date, time, offset};
}

// Replaces one element holding `value`, padded to an even length as PS3.5 7.1 asks: UIDs with NUL, text with space.
void Put(gdcm::DataSet& data, gdcm::Tag tag, gdcm::VR vr, std::string value) {
  if (value.size() % 2 != 0) value += vr == gdcm::VR::UI ? '\0' : ' ';
  gdcm::DataElement element(tag);
  element.SetVR(vr);
  element.SetByteValue(value.data(), gdcm::VL(static_cast<std::uint32_t>(value.size())));
  data.Replace(element);
}

void PutUnsignedShort(gdcm::DataSet& data, gdcm::Tag tag, int value) {
  const char bytes[2] = {static_cast<char>(value & 0xff), static_cast<char>((value >> 8) & 0xff)};  // little endian
  gdcm::DataElement element(tag);
  element.SetVR(gdcm::VR::US);
  element.SetByteValue(bytes, 2);
  data.Replace(element);
}

bool NeedsUtf8(const SourceStudy& source, const CheckedRecipe& recipe) {
  for (const std::string* text : {&source.patient_name, &source.patient_id, &source.study_id, &source.accession_number,
                                  &source.referring_physician, &source.study_description, &recipe.preset}) {
    if (!IsAscii(*text)) return true;
  }
  return false;
}

// Patient, General Study: copied, so the capture files under the source's patient and study.
void PutPatientAndStudy(gdcm::DataSet& data, const SourceStudy& source) {
  Put(data, gdcm::Tag(0x0010, 0x0010), gdcm::VR::PN, source.patient_name);
  Put(data, gdcm::Tag(0x0010, 0x0020), gdcm::VR::LO, source.patient_id);
  Put(data, gdcm::Tag(0x0010, 0x0030), gdcm::VR::DA, source.patient_birth_date);
  Put(data, gdcm::Tag(0x0010, 0x0040), gdcm::VR::CS, source.patient_sex);
  Put(data, gdcm::Tag(0x0020, 0x000d), gdcm::VR::UI, source.study_uid);
  Put(data, gdcm::Tag(0x0020, 0x0010), gdcm::VR::SH, source.study_id);
  Put(data, gdcm::Tag(0x0008, 0x0020), gdcm::VR::DA, source.study_date);
  Put(data, gdcm::Tag(0x0008, 0x0030), gdcm::VR::TM, source.study_time);
  Put(data, gdcm::Tag(0x0008, 0x0050), gdcm::VR::SH, source.accession_number);
  Put(data, gdcm::Tag(0x0008, 0x0090), gdcm::VR::PN, source.referring_physician);
  Put(data, gdcm::Tag(0x0008, 0x1030), gdcm::VR::LO, source.study_description);
}

std::string SeriesDescription(const std::string& preset) {
  if (preset.empty()) return std::string(kDescriptionPrefix);
  const std::string prefix = std::string(kDescriptionPrefix) + ": ";
  return prefix + CutToCharacters(preset, kLoCharacters - prefix.size());
}

// General Series, SC Equipment, General Equipment, General Image, SOP Common: this capture's own.
void PutSeriesAndInstance(gdcm::DataSet& data, const SecondaryCaptureUids& uids, const CheckedRecipe& recipe) {
  const Timestamp now = Now();
  Put(data, gdcm::Tag(0x0008, 0x0016), gdcm::VR::UI, kSecondaryCaptureSopClass);
  Put(data, gdcm::Tag(0x0008, 0x0018), gdcm::VR::UI, uids.sop_instance_uid);
  Put(data, gdcm::Tag(0x0020, 0x000e), gdcm::VR::UI, uids.series_uid);
  Put(data, gdcm::Tag(0x0008, 0x0060), gdcm::VR::CS, "OT");
  Put(data, gdcm::Tag(0x0008, 0x0064), gdcm::VR::CS, "WSD");  // workstation
  Put(data, gdcm::Tag(0x0008, 0x103e), gdcm::VR::LO, SeriesDescription(recipe.preset));
  Put(data, gdcm::Tag(0x0020, 0x0011), gdcm::VR::IS, std::to_string(kRenderSeriesNumber));
  Put(data, gdcm::Tag(0x0020, 0x0013), gdcm::VR::IS, "1");
  Put(data, gdcm::Tag(0x0020, 0x0020), gdcm::VR::CS, "");  // Patient Orientation: type 2, unknown for a render
  // Laterality: type 2C, required for a paired body part. The source
  // series' body part is not known here, so it is sent empty, "unknown"
  // (dciodvfy: an error when absent, a warning when empty; docs/pacs.md).
  Put(data, gdcm::Tag(0x0020, 0x0060), gdcm::VR::CS, "");
  Put(data, gdcm::Tag(0x0008, 0x0008), gdcm::VR::CS, "DERIVED\\SECONDARY");
  for (const gdcm::Tag& date :
       {gdcm::Tag(0x0008, 0x0012), gdcm::Tag(0x0008, 0x0021), gdcm::Tag(0x0008, 0x0023), gdcm::Tag(0x0018, 0x1012)}) {
    Put(data, date, gdcm::VR::DA, now.date);  // instance creation, series, content, secondary capture
  }
  for (const gdcm::Tag& time :
       {gdcm::Tag(0x0008, 0x0013), gdcm::Tag(0x0008, 0x0031), gdcm::Tag(0x0008, 0x0033), gdcm::Tag(0x0018, 0x1014)}) {
    Put(data, time, gdcm::VR::TM, now.time);
  }
  Put(data, gdcm::Tag(0x0008, 0x0201), gdcm::VR::SH, now.offset);
  Put(data, gdcm::Tag(0x0008, 0x0070), gdcm::VR::LO, "cinevol");
  Put(data, gdcm::Tag(0x0018, 0x1016), gdcm::VR::LO, "cinevol");
  Put(data, gdcm::Tag(0x0018, 0x1019), gdcm::VR::LO, recipe.version);
  Put(data, gdcm::Tag(0x0018, 0x1020), gdcm::VR::LO, recipe.version);
}

// Image Pixel, less the pixels themselves (AppendPixelData): 8-bit RGB, interleaved.
void PutImagePixelModule(gdcm::DataSet& data, const SecondaryCaptureImage& image) {
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0002), 3);  // samples per pixel
  Put(data, gdcm::Tag(0x0028, 0x0004), gdcm::VR::CS, "RGB");
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0006), 0);  // planar configuration: RGBRGB...
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0010), image.height);
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0011), image.width);
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0100), 8);      // bits allocated
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0101), 8);      // bits stored
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0102), 7);      // high bit
  PutUnsignedShort(data, gdcm::Tag(0x0028, 0x0103), 0);      // unsigned
  Put(data, gdcm::Tag(0x0028, 0x0301), gdcm::VR::CS, "NO");  // the picture carries no patient text
  Put(data, gdcm::Tag(0x0028, 0x2110), gdcm::VR::CS, "00");  // never lossy-compressed
}

// The recipe for a program (the private block) and where to find it for a person (comments, derivation).
void PutRecipe(gdcm::DataSet& data, const std::string& recipe_json, const CheckedRecipe& recipe) {
  Put(data, gdcm::Tag(kRecipeGroup, 0x0010), gdcm::VR::LO, kRecipeCreator);
  Put(data, gdcm::Tag(kRecipeGroup, 0x1000 | kRecipeElement), gdcm::VR::UT, recipe_json);
  const std::string preset = recipe.preset.empty() ? "" : fmt::format(" with preset \"{}\"", recipe.preset);
  Put(data, gdcm::Tag(0x0008, 0x2111), gdcm::VR::ST,
      fmt::format("Volume rendering of series {}{} by cinevol {}", recipe.source_series_uid, preset, recipe.version));
  Put(data, gdcm::Tag(0x0020, 0x4000), gdcm::VR::LT,
      fmt::format("cinevol render of series {}{}. To render it again: the recipe (the scene as proto3 JSON, the "
                  "series, the version) is in private tag ({:04X},10{:02X}) of creator \"{}\".",
                  recipe.source_series_uid, preset, kRecipeGroup, kRecipeElement, kRecipeCreator));
}

// The file meta header and the data set, as GDCM writes them.
std::string WriteWithGdcm(const gdcm::DataSet& data) {
  gdcm::Writer writer;
  writer.GetFile().SetDataSet(data);
  writer.GetFile().GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  std::ostringstream out;
  writer.SetStream(out);
  if (!writer.Write()) throw std::runtime_error("GDCM could not write the Secondary Capture");
  return std::move(out).str();
}

// Pixel Data (7FE0,0010), OB, appended after GDCM's output: it sorts last among the data set's tags, and appending
// spares two copies of a picture that may be 768 MiB.
void AppendPixelData(std::string& file, const std::vector<std::uint8_t>& rgb) {
  const std::uint32_t length = static_cast<std::uint32_t>(rgb.size() + rgb.size() % 2);
  const char header[12] = {'\xe0',
                           '\x7f',
                           '\x10',
                           '\x00',
                           'O',
                           'B',
                           '\0',
                           '\0',
                           static_cast<char>(length & 0xff),
                           static_cast<char>((length >> 8) & 0xff),
                           static_cast<char>((length >> 16) & 0xff),
                           static_cast<char>(length >> 24)};
  file.reserve(file.size() + sizeof header + length);
  file.append(header, sizeof header);
  file.append(reinterpret_cast<const char*>(rgb.data()), rgb.size());
  if (rgb.size() % 2 != 0) file += '\0';
}

// ---- Reading ----
// Not with GDCM: Debian's GDCM keeps its assertions, and some malformed files abort the process in them; a file
// from a PACS is not trusted. A capture is read as MakeSecondaryCapture writes it: Part 10, explicit VR little
// endian, elements of defined length, up to the pixels, which are never read.

constexpr std::string_view kExplicitVrLittleEndian = "1.2.840.10008.1.2.1";
constexpr std::uint32_t kTransferSyntaxTag = 0x00020010;
constexpr std::uint32_t kSopClassTag = 0x00080016;
constexpr std::uint16_t kPixelDataGroup = 0x7fe0;

using Elements = std::map<std::uint32_t, std::string_view>;  // group << 16 | element -> value

[[noreturn]] void NotARender(std::string_view why) { throw InputError(fmt::format("not a cinevol render: {}", why)); }

std::uint32_t LittleEndian(std::string_view bytes, std::size_t at, int size) {
  std::uint32_t value = 0;
  for (int i = size - 1; i >= 0; --i) value = value << 8 | static_cast<unsigned char>(bytes[at + i]);
  return value;
}

// The group of the element at `at`, which must have room for at least a short element header.
std::uint16_t GroupAt(std::string_view bytes, std::size_t at) {
  if (bytes.size() - at < 8) NotARender("it ends inside an element");
  return static_cast<std::uint16_t>(LittleEndian(bytes, at, 2));
}

// PS3.5 7.1.2: these VRs have two reserved bytes and a 32-bit length.
bool HasLongLength(std::string_view vr) {
  for (std::string_view long_vr : {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"}) {
    if (vr == long_vr) return true;
  }
  return false;
}

// The explicit VR little endian element at `at` (GroupAt checked there is one), `at` moved past it.
std::pair<std::uint32_t, std::string_view> NextElement(std::string_view bytes, std::size_t& at) {
  const std::uint32_t tag = LittleEndian(bytes, at, 2) << 16 | LittleEndian(bytes, at + 2, 2);
  const std::string_view vr = bytes.substr(at + 4, 2);
  if (vr[0] < 'A' || vr[0] > 'Z' || vr[1] < 'A' || vr[1] > 'Z') NotARender("it is not in explicit VR");
  std::size_t header = 8;
  std::uint32_t length = LittleEndian(bytes, at + 6, 2);
  if (HasLongLength(vr)) {
    if (bytes.size() - at < 12) NotARender("it ends inside an element");
    header = 12;
    length = LittleEndian(bytes, at + 8, 4);
  }
  if (length == 0xffffffff) NotARender("it holds an element of undefined length");
  if (bytes.size() - at - header < length) NotARender("it ends inside an element");
  const std::string_view value = bytes.substr(at + header, length);
  at += header + length;
  return {tag, value};
}

std::string TextOf(const Elements& elements, std::uint32_t tag) {
  const auto element = elements.find(tag);
  return element == elements.end() ? std::string() : WithoutTrailingSpaces(std::string(element->second));
}

void CheckSopClass(std::string_view value) {
  const std::string sop_class = WithoutTrailingSpaces(std::string(value));
  if (sop_class != kSecondaryCaptureSopClass) {
    NotARender(fmt::format("SOP class {}, not Secondary Capture", IsValidUid(sop_class) ? sop_class : "(no UID)"));
  }
}

// The file meta header and the data set up to the pixels; a file of another SOP class is refused as soon as its
// class is read.
Elements ReadUpToPixels(std::string_view bytes) {
  if (bytes.size() < 132 || bytes.substr(128, 4) != "DICM") NotARender("not a DICOM Part 10 file");
  Elements elements;
  std::size_t at = 132;
  while (at < bytes.size() && GroupAt(bytes, at) == 0x0002) elements.insert(NextElement(bytes, at));
  if (TextOf(elements, kTransferSyntaxTag) != kExplicitVrLittleEndian) {
    NotARender("its transfer syntax is not explicit VR little endian");
  }
  while (at < bytes.size() && GroupAt(bytes, at) < kPixelDataGroup) {
    const auto element = NextElement(bytes, at);
    if (element.first == kSopClassTag) CheckSopClass(element.second);
    elements.insert(element);
  }
  if (elements.count(kSopClassTag) == 0) NotARender("it has no SOP class");
  return elements;
}

// The recipe, in whichever private block of kRecipeGroup its creator reserved (PS3.5 7.8.1).
std::string RecipeJsonOf(const Elements& elements) {
  for (std::uint32_t block = 0x10; block <= 0xff; ++block) {
    if (TextOf(elements, std::uint32_t{kRecipeGroup} << 16 | block) != kRecipeCreator) continue;
    const std::uint32_t tag = std::uint32_t{kRecipeGroup} << 16 | block << 8 | kRecipeElement;
    if (elements.count(tag) == 0) break;
    return TextOf(elements, tag);
  }
  NotARender(fmt::format("no private block \"{}\" holding a recipe", kRecipeCreator));
}

int UnsignedShortOf(const Elements& elements, std::uint32_t tag) {
  const auto element = elements.find(tag);
  if (element == elements.end() || element->second.size() != 2) return 0;
  return static_cast<int>(LittleEndian(element->second, 0, 2));
}

std::string StringField(const Struct& recipe, const char* name) {
  const auto field = recipe.fields().find(name);
  if (field == recipe.fields().end() || !field->second.has_string_value()) {
    NotARender(fmt::format("its recipe has no text \"{}\"", name));
  }
  return field->second.string_value();
}

// The recipe's scene, source series, version and preset into `capture`.
void ReadRecipe(ReadCapture& capture) {
  if (capture.recipe_json.size() > kMaxRecipeBytes) NotARender("its recipe is too long");
  Value recipe;
  if (!ParseJsonObject(capture.recipe_json, recipe)) NotARender("its recipe is not a JSON object");
  const Struct& fields = recipe.struct_value();
  const auto scene = fields.fields().find("scene");
  if (scene == fields.fields().end() || !scene->second.has_struct_value()) NotARender("its recipe has no scene");
  if (!google::protobuf::util::MessageToJsonString(scene->second, &capture.scene_json).ok()) {
    NotARender("its scene cannot be written as JSON");
  }
  capture.source_series_uid = StringField(fields, "sourceSeriesUid");
  if (!IsValidUid(capture.source_series_uid)) NotARender("its recipe's series is not a UID");
  capture.cinevol_version = StringField(fields, "cinevolVersion");
  const auto preset = fields.fields().find("preset");
  if (preset != fields.fields().end() && preset->second.has_string_value()) {
    capture.preset = preset->second.string_value();
  }
}

}  // namespace

std::string NewUid() {
  std::random_device random;
  unsigned __int128 uuid = 0;
  for (int i = 0; i < 4; ++i) uuid = uuid << 32 | random();
  // RFC 4122: version 4 (random) in bits 76-79, variant 10 in bits 62-63.
  uuid = (uuid & ~(static_cast<unsigned __int128>(0xf) << 76)) | static_cast<unsigned __int128>(0x4) << 76;
  uuid = (uuid & ~(static_cast<unsigned __int128>(0x3) << 62)) | static_cast<unsigned __int128>(0x2) << 62;
  std::string digits;
  for (; uuid != 0; uuid /= 10) digits.insert(digits.begin(), static_cast<char>('0' + int(uuid % 10)));
  return "2.25." + digits;
}

std::string MakeSecondaryCapture(const SourceStudy& given_source, const SecondaryCaptureImage& image,
                                 const RenderRecipe& given_recipe, SecondaryCaptureUids* uids_out) {
  const SourceStudy source = CheckedSource(given_source);
  CheckImage(image);
  const CheckedRecipe recipe = CheckRecipe(given_recipe, source);
  const SecondaryCaptureUids uids{source.study_uid, NewUid(), NewUid()};
  gdcm::DataSet data;
  if (NeedsUtf8(source, recipe)) Put(data, gdcm::Tag(0x0008, 0x0005), gdcm::VR::CS, "ISO_IR 192");
  PutPatientAndStudy(data, source);
  PutSeriesAndInstance(data, uids, recipe);
  PutImagePixelModule(data, image);
  PutRecipe(data, RecipeJson(given_recipe.scene_json, recipe), recipe);
  std::string file = WriteWithGdcm(data);
  AppendPixelData(file, image.rgb);
  if (uids_out != nullptr) *uids_out = uids;
  return file;
}

ReadCapture ReadSecondaryCapture(const std::string& part10_bytes) {
  const Elements elements = ReadUpToPixels(part10_bytes);
  ReadCapture capture;
  capture.recipe_json = RecipeJsonOf(elements);
  ReadRecipe(capture);
  capture.uids = {TextOf(elements, 0x0020000d), TextOf(elements, 0x0020000e), TextOf(elements, 0x00080018)};
  capture.patient_id = TextOf(elements, 0x00100020);
  capture.patient_name = TextOf(elements, 0x00100010);
  capture.width = UnsignedShortOf(elements, 0x00280011);
  capture.height = UnsignedShortOf(elements, 0x00280010);
  return capture;
}

}  // namespace cinevol::pacs

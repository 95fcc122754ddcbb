// Reading DICOM JSON without trusting it.
#include "pacs/dicom_json.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <cctype>
#include <cmath>
#include <stdexcept>

namespace cinevol::pacs {
namespace {

using google::protobuf::ListValue;
using google::protobuf::Struct;
using google::protobuf::Value;

constexpr std::int64_t kMaxCount = std::int64_t{1} << 31;
// DICOM JSON nests three levels per sequence; 32 allows sequences 10 deep, more than a
// search or store answer holds, and stays inside protobuf's own recursion limit.
constexpr int kMaxJsonDepth = 32;

std::string Cut(const std::string& text) { return text.substr(0, kMaxDicomText); }

std::string TextOf(const Value& value) {
  if (value.kind_case() == Value::kStringValue) return Cut(value.string_value());
  if (value.kind_case() == Value::kNumberValue && std::isfinite(value.number_value())) {
    return fmt::format("{}", value.number_value());
  }
  return {};
}

std::optional<std::int64_t> CountOf(const Value& value) {
  if (value.kind_case() == Value::kNumberValue) {
    const double number = value.number_value();
    if (!std::isfinite(number) || number < 0 || number >= double(kMaxCount) || number != std::floor(number)) {
      return std::nullopt;
    }
    return static_cast<std::int64_t>(number);
  }
  if (value.kind_case() != Value::kStringValue) return std::nullopt;
  std::string_view text = value.string_value();
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);  // IS values may be space-padded
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (text.empty() || text.size() > 10) return std::nullopt;
  std::int64_t count = 0;
  for (char c : text) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
    count = count * 10 + (c - '0');
  }
  if (count >= kMaxCount) return std::nullopt;
  return count;
}

}  // namespace

const ListValue* DicomJsonDataset::Values(std::uint32_t tag) const {
  // PS3.18 F.2 writes tags in upper-case hex; some servers write lower case.
  for (const std::string& key : {fmt::format("{:08X}", tag), fmt::format("{:08x}", tag)}) {
    const auto attribute = object_->fields().find(key);
    if (attribute == object_->fields().end() || !attribute->second.has_struct_value()) continue;
    const auto& fields = attribute->second.struct_value().fields();
    const auto values = fields.find("Value");
    if (values == fields.end() || !values->second.has_list_value()) return nullptr;
    return &values->second.list_value();
  }
  return nullptr;
}

std::string DicomJsonDataset::Text(std::uint32_t tag) const {
  const ListValue* values = Values(tag);
  return values != nullptr && values->values_size() > 0 ? TextOf(values->values(0)) : std::string();
}

std::vector<std::string> DicomJsonDataset::Texts(std::uint32_t tag, std::size_t max_values) const {
  std::vector<std::string> texts;
  const ListValue* values = Values(tag);
  for (int i = 0; values != nullptr && i < values->values_size() && texts.size() < max_values; ++i) {
    std::string text = TextOf(values->values(i));
    if (!text.empty()) texts.push_back(std::move(text));
  }
  return texts;
}

std::string DicomJsonDataset::PersonName(std::uint32_t tag) const {
  const ListValue* values = Values(tag);
  if (values == nullptr || values->values_size() == 0) return {};
  const Value& first = values->values(0);
  if (!first.has_struct_value()) return TextOf(first);
  const auto& groups = first.struct_value().fields();
  const auto alphabetic = groups.find("Alphabetic");
  return alphabetic == groups.end() ? std::string() : TextOf(alphabetic->second);
}

std::optional<std::int64_t> DicomJsonDataset::Count(std::uint32_t tag) const {
  const ListValue* values = Values(tag);
  if (values == nullptr || values->values_size() == 0) return std::nullopt;
  return CountOf(values->values(0));
}

std::vector<DicomJsonDataset> DicomJsonDataset::Items(std::uint32_t tag, std::size_t max_items) const {
  std::vector<DicomJsonDataset> items;
  const ListValue* values = Values(tag);
  for (int i = 0; values != nullptr && i < values->values_size() && items.size() < max_items; ++i) {
    if (values->values(i).has_struct_value()) items.emplace_back(values->values(i).struct_value());
  }
  return items;
}

bool NestsDeeperThan(std::string_view json, int limit) {
  int depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < json.size(); ++i) {
    const char c = json[i];
    if (in_string) {
      if (c == '\\') ++i;  // an escaped character, perhaps a quote
      if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > limit) return true;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return false;
}

std::vector<DicomJsonDataset> ParseDicomJson(std::string_view json, Value& storage) {
  storage.Clear();
  if (NestsDeeperThan(json, kMaxJsonDepth)) {
    throw std::invalid_argument(fmt::format("the answer nests more than {} levels deep", kMaxJsonDepth));
  }
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(json), &storage);
  if (!status.ok()) throw std::invalid_argument("the answer is not valid JSON");
  std::vector<DicomJsonDataset> datasets;
  if (storage.has_struct_value()) {
    datasets.emplace_back(storage.struct_value());
  } else if (storage.has_list_value()) {
    for (const Value& item : storage.list_value().values()) {
      if (item.has_struct_value()) datasets.emplace_back(item.struct_value());
    }
  } else if (storage.kind_case() != Value::kNullValue) {  // some servers answer an empty search with null
    throw std::invalid_argument("the answer is JSON, but neither an array of data sets nor one data set");
  }
  return datasets;
}

bool IsValidUid(std::string_view uid) {
  if (uid.empty() || uid.size() > 64 || uid.front() == '.' || uid.back() == '.') return false;
  char previous = 0;
  for (char c : uid) {
    if (!(std::isdigit(static_cast<unsigned char>(c)) || c == '.')) return false;
    if (c == '.' && previous == '.') return false;
    previous = c;
  }
  return true;
}

}  // namespace cinevol::pacs

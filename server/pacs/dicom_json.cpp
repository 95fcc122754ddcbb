// Reading DICOM JSON without trusting it.
#include "pacs/dicom_json.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "core/log_safe.h"

namespace cinevol::pacs {
namespace {

using Kind = JsonDocument::Kind;
using Ref = JsonDocument::Ref;

constexpr std::int64_t kMaxCount = std::int64_t{1} << 31;
// DICOM JSON nests three levels per sequence; 32 allows sequences 10 deep,
// more than a search or store answer holds.
constexpr int kMaxJsonDepth = 32;

std::string TextOf(Ref value) {
  if (value.is(Kind::kString)) return CleanText(value.text());
  if (value.is(Kind::kNumber) && std::isfinite(value.number())) return fmt::format("{}", value.number());
  return {};
}

std::optional<std::int64_t> CountOf(Ref value) {
  if (value.is(Kind::kNumber)) {
    const double number = value.number();
    if (!std::isfinite(number) || number < 0 || number >= double(kMaxCount) || number != std::floor(number)) {
      return std::nullopt;
    }
    return static_cast<std::int64_t>(number);
  }
  if (!value.is(Kind::kString)) return std::nullopt;
  std::string_view text = value.text();
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

// A JSON number, or a numeric string as some servers write DS values ("0.5 "); nothing else.
std::optional<double> NumberOf(Ref value) {
  if (value.is(Kind::kNumber)) {
    return std::isfinite(value.number()) ? std::optional<double>(value.number()) : std::nullopt;
  }
  if (!value.is(Kind::kString) || value.text().size() > 32) return std::nullopt;  // a DS holds 16 characters
  const std::string text(value.text());
  char* end = nullptr;
  const double number = std::strtod(text.c_str(), &end);
  while (end && *end == ' ') ++end;
  if (end == text.c_str() || !end || *end != '\0' || !std::isfinite(number)) return std::nullopt;
  return number;
}

}  // namespace

std::string CleanText(std::string_view text, std::size_t max_bytes) {
  static constexpr std::string_view kReplacement = "\xEF\xBF\xBD";  // U+FFFD
  std::string clean;
  while (!text.empty()) {
    const std::size_t length = Utf8SequenceLength(text);
    const std::string_view character = length > 0 ? text.substr(0, length) : kReplacement;
    if (clean.size() + character.size() > max_bytes) break;
    clean += character;
    text.remove_prefix(std::max<std::size_t>(length, 1));
  }
  return clean;
}

std::vector<Ref> DicomJsonDataset::Values(std::uint32_t tag) const {
  // PS3.18 F.2 writes tags in upper-case hex; some servers write lower case.
  for (const std::string& key : {fmt::format("{:08X}", tag), fmt::format("{:08x}", tag)}) {
    const Ref attribute = object_.member(key);
    if (!attribute.is(Kind::kObject)) continue;
    return attribute.member("Value").children();  // none unless an array
  }
  return {};
}

std::string DicomJsonDataset::Text(std::uint32_t tag) const {
  const std::vector<Ref> values = Values(tag);
  return values.empty() ? std::string() : TextOf(values.front());
}

std::vector<std::string> DicomJsonDataset::Texts(std::uint32_t tag, std::size_t max_values) const {
  std::vector<std::string> texts;
  for (Ref value : Values(tag)) {
    if (texts.size() >= max_values) break;
    std::string text = TextOf(value);
    if (!text.empty()) texts.push_back(std::move(text));
  }
  return texts;
}

std::string DicomJsonDataset::PersonName(std::uint32_t tag) const {
  const std::vector<Ref> values = Values(tag);
  if (values.empty()) return {};
  const Ref first = values.front();
  return first.is(Kind::kObject) ? TextOf(first.member("Alphabetic")) : TextOf(first);
}

std::optional<std::int64_t> DicomJsonDataset::Count(std::uint32_t tag) const {
  const std::vector<Ref> values = Values(tag);
  return values.empty() ? std::nullopt : CountOf(values.front());
}

std::vector<double> DicomJsonDataset::Numbers(std::uint32_t tag, std::size_t max_values) const {
  std::vector<double> numbers;
  for (Ref value : Values(tag)) {
    const std::optional<double> number = NumberOf(value);
    if (numbers.size() >= max_values || !number) break;
    numbers.push_back(*number);
  }
  return numbers;
}

std::vector<DicomJsonDataset> DicomJsonDataset::Items(std::uint32_t tag, std::size_t max_items) const {
  std::vector<DicomJsonDataset> items;
  for (Ref value : Values(tag)) {
    if (items.size() >= max_items) break;
    if (value.is(Kind::kObject)) items.emplace_back(value);
  }
  return items;
}

std::vector<DicomJsonDataset> ParseDicomJson(std::string_view json, JsonDocument& storage,
                                             const std::atomic<bool>* cancel) {
  storage = JsonDocument::Parse(json, {.max_depth = kMaxJsonDepth}, cancel);
  const Ref root = storage.root();
  std::vector<DicomJsonDataset> datasets;
  if (root.is(Kind::kObject)) {
    datasets.emplace_back(root);
  } else if (root.is(Kind::kArray)) {
    for (Ref item : root.children()) {
      if (item.is(Kind::kObject)) datasets.emplace_back(item);
    }
  } else if (!root.is(Kind::kNull)) {  // some servers answer an empty search with null
    throw JsonError("the answer is JSON, but neither an array of data sets nor one data set");
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

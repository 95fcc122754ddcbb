// Text headers' lines, field names and data file fields.
#include "io/formats/header_text.h"

#include <algorithm>
#include <cctype>
#include <sstream>

#include <fmt/format.h>

#include "core/volume.h"

namespace fs = std::filesystem;

namespace cinevol::formats {
namespace {

// A header naming more files than a volume has slices is not a volume.
constexpr long long kMaxListedFiles = kMaxVoxelsPerAxis;

}  // namespace

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::string line;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c != '\r' && c != '\n') {
      line += c;
      continue;
    }
    lines.push_back(line.substr(0, line.find('\0')));
    line.clear();
    if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
  }
  if (!line.empty()) lines.push_back(line.substr(0, line.find('\0')));
  return lines;
}

std::int64_t OffsetAfterLines(const std::string& text, std::size_t lines) {
  std::size_t i = 0;
  for (std::size_t n = 0; n < lines; ++n) {
    while (i < text.size() && text[i] != '\r' && text[i] != '\n') ++i;
    if (i == text.size()) return -1;
    if (text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
    ++i;
  }
  return std::int64_t(i);
}

std::string NormalKey(const std::string& key) {
  std::string out;
  for (char c : key) {
    c = char(std::tolower(static_cast<unsigned char>(c)));
    if (c != ' ' && c != '\t') out += c;
  }
  return out;
}

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

std::string TrimBlanks(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  return first == std::string::npos ? "" : s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

void AddFile(References& refs, const fs::path& dir, const std::string& name) {
  if (name == "-") {
    refs.files.push_back("/dev/stdin");
  } else {
    refs.files.push_back(!name.empty() && name[0] == '/' ? fs::path(name) : dir / name);
  }
}

void AddPattern(References& refs, const fs::path& dir, const std::string& value, std::string* dim) {
  std::istringstream in(value);
  std::string format;
  long long lo = 0, hi = 0, step = 0;
  in >> format;
  if (!(in >> lo >> hi >> step)) {
    refs.problem = "a file name pattern without min, max and step";
    return;
  }
  if (std::string d; dim && in >> d) *dim = d;
  const std::size_t percent = format.find('%');
  std::size_t i = percent + 1;
  const bool zero = i < format.size() && format[i] == '0';
  if (zero) ++i;
  const std::size_t digits = i;
  while (i < format.size() && std::isdigit(static_cast<unsigned char>(format[i]))) ++i;
  const int width = i > digits && i - digits <= 2 ? std::stoi(format.substr(digits, i - digits)) : 0;
  if (i >= format.size() || format[i] != 'd' || i - digits > 2 || format.find('%', i) != std::string::npos) {
    refs.problem = "an unsupported file name pattern";
    return;
  }
  if (step == 0 || (hi - lo) / step < 0 || (hi - lo) / step >= kMaxListedFiles) {
    refs.problem = fmt::format("a file name pattern for other than 1 to {} files", kMaxListedFiles);
    return;
  }
  const std::string prefix = format.substr(0, percent), suffix = format.substr(i + 1);
  for (long long v = lo; step > 0 ? v <= hi : v >= hi; v += step) {
    const std::string number = zero ? fmt::format("{:0{}}", v, std::max(width, 1))
                                    : fmt::format("{:>{}}", v, std::max(width, 1));
    AddFile(refs, dir, prefix + number + suffix);
  }
}

void AddList(References& refs, const fs::path& dir, const std::vector<std::string>& lines, std::size_t first,
             bool truncated) {
  for (std::size_t i = first; i < lines.size(); ++i) {
    if (!lines[i].empty()) AddFile(refs, dir, lines[i]);
  }
  if (truncated) refs.problem = fmt::format("a file list longer than {} bytes", kMaxHeaderBytes);
  if (refs.files.size() > std::size_t(kMaxListedFiles)) {
    refs.problem = fmt::format("a list of more than {} files", kMaxListedFiles);
  }
}

}  // namespace cinevol::formats

// What stands in front of teem inside the cage: header text, payload, rewrites.
#include "io/formats/nrrd/checks.h"

#include <itkImageIOBase.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/formats/header_text.h"
#include "io/formats/nrrd/references.h"

namespace fs = std::filesystem;

namespace cinevol::formats::nrrd {
namespace {

// The lines teem skips before the voxels: a header's own `line skip` field.
std::int64_t LineSkip(const std::string& line, const std::string& shown) {
  const std::string value = line.substr(std::min(line.size(), line.find_first_not_of(" \t", line.find(':') + 1)));
  std::int64_t n = 0;
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
  if (ec != std::errc() || n < 0) throw InputError(fmt::format("{}: 'line skip' is not a count", shown));
  return n;
}

}  // namespace

// A NRRD header whose other files are where the cage placed them (`named`,
// in the header's order) and, with `drop_space`, without its `space` line:
// some published detached headers give both `space` and per-axis `spacings`,
// which teem refuses, and the intent is plain (the spacings are the voxel
// size). Attached voxels are read from `header` itself past its lines.
std::string RewrittenHeader(const fs::path& header, const std::vector<fs::path>& named, bool drop_space,
                            const std::string& shown) {
  const Header h = ParseHeader(header, shown);
  if (!h.references.problem.empty()) throw InputError(fmt::format("{}: {}", shown, h.references.problem));
  if (!h.attached && h.references.files.size() != named.size()) {
    throw InputError(fmt::format("{}: the header changed while it was read", shown));
  }
  std::string out;
  std::int64_t line_skip = 0;
  for (const std::string& line : h.lines) {
    const std::string key = FieldName(line);
    if (drop_space && key == "space") continue;
    if (h.attached && key == "lineskip") {
      line_skip = LineSkip(line, shown);
      continue;
    }
    out += line + "\n";
  }
  std::vector<std::string> files;
  for (const fs::path& f : h.attached ? std::vector<fs::path>{header} : named) {
    const std::string path = fs::absolute(f).lexically_normal().string();
    if (path.find_first_of("\r\n") != std::string::npos) {
      throw InputError(fmt::format("{}: the header's 'data file' names a file that cannot be read", shown));
    }
    files.push_back(path);
  }
  if (h.attached) out += fmt::format("line skip: {}\n", std::int64_t(h.line_count) + line_skip);
  if (h.listed) {
    out += "data file: LIST" + (h.list_dim.empty() ? "" : " " + h.list_dim) + "\n";
    for (const std::string& f : files) out += f + "\n";
  } else {
    out += "data file: " + files.at(0) + "\n";
  }
  return out;
}

bool IsSpaceWithSpacingsError(const std::string& description) {
  return description.find("ScalarWithSpace") != std::string::npos;
}

// teem copies a per-axis field's values ("sizes", "spacings", "space
// directions", ...) through fixed buffers: a line of about 1,000 characters
// (extra values, trailing blanks) aborts it under _FORTIFY_SOURCE. Real
// lines are a few dozen characters; free text ("content", comments and
// key/value pairs) is not limited.
bool StatesOrientation(const fs::path& path, const std::string& shown) {
  for (const std::string& line : ParseHeader(path, shown).lines) {
    const std::string field = FieldName(line);
    if (field == "space" || field == "spacedirections") return true;
  }
  return false;
}

void CheckHeaderText(const fs::path& path, const std::string& shown) {
  constexpr std::size_t kMaxFieldLine = 512;
  const Header h = ParseHeader(path, shown);
  for (std::size_t i = 1; i < h.lines.size(); ++i) {
    const std::string& line = h.lines[i];
    const std::string key = FieldName(line);
    if (key.empty() || key == "content" || line.find(":=") != std::string::npos) continue;
    if (line.size() > kMaxFieldLine) {
      throw InputError(fmt::format("{}: the header's '{}' line has {} characters; cinevol reads NRRD field lines of "
                                   "up to {}",
                                   shown, line.substr(0, line.find(':')), line.size(), kMaxFieldLine));
    }
  }
}

// teem (ITK's NRRD reader) leaks its state whenever the voxels cannot be
// read (a short or damaged payload, a bad number in ASCII data): a few KiB
// per load, tens of KiB for gzip. So the payload of a NRRD in one file
// (attached, or one detached data file) is checked here first, as teem will
// read it. Returns "" when it holds every voxel, else what is wrong.
std::string PayloadProblem(itk::ImageIOBase& io, const fs::path& path, const std::string& shown) {
  const Header h = ParseHeader(path, shown);
  if (h.listed || !h.references.problem.empty() || (!h.attached && h.references.files.size() != 1)) return "";
  std::string encoding = "raw";
  std::int64_t line_skip = 0, byte_skip = 0;
  for (const std::string& line : h.lines) {
    const std::string key = FieldName(line);
    if (key != "encoding" && key != "lineskip" && key != "byteskip") continue;
    const std::string value = TrimBlanks(line.substr(line.find(':') + 1));
    if (key == "encoding") {
      encoding.clear();
      for (char c : value) encoding += char(std::tolower(static_cast<unsigned char>(c)));
      continue;
    }
    std::int64_t n = 0;
    const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
    if (ec != std::errc() || end != value.data() + value.size() || n < (key == "byteskip" ? -1 : 0)) {
      return fmt::format("'{}' is not a valid count", key == "byteskip" ? "byte skip" : "line skip");
    }
    (key == "byteskip" ? byte_skip : line_skip) = n;
  }
  const fs::path data = h.attached ? path : h.references.files.front();
  const file_checks::FileStream stream = file_checks::OpenRegularStream(data);
  if (!stream) return "cannot read the file that 'data file' names";
  std::FILE* f = stream.get();
  // Where the data begin: past the header's lines (attached) and `line skip` lines.
  std::int64_t start = 0;
  if (h.attached) {
    start = OffsetAfterLines(file_checks::ReadHead(data, kMaxHeaderBytes + 1, shown), h.line_count);
    if (start < 0) return "the header does not end before the data";
  }
  if (std::fseek(f, long(start), SEEK_SET) != 0) return "cannot read the data";
  for (std::int64_t n = 0; n < line_skip; ++n) {
    int c;
    while ((c = std::getc(f)) != EOF && c != '\n') {
    }
    if (c == EOF) return fmt::format("truncated: 'line skip' {} runs past the end of the file", line_skip);
  }
  start = std::ftell(f);
  const std::int64_t expected = std::int64_t(io.GetImageSizeInBytes());
  std::error_code ec;
  const std::int64_t size = std::int64_t(fs::file_size(data, ec));
  if (ec) return "cannot read the data";
  const std::string shown_data = h.attached ? "the file" : fmt::format("'{}'", data.filename().string());
  if (encoding == "raw") {
    const std::int64_t available = byte_skip < 0 ? size - start : size - start - byte_skip;
    if (available < expected) {
      return fmt::format("truncated: {} voxel bytes expected, {} holds {}", expected, shown_data,
                         std::max<std::int64_t>(0, available));
    }
    return "";
  }
  if (byte_skip < 0) return fmt::format("'byte skip: -1' is for raw data only, not '{}'", encoding);
  if (encoding == "gzip" || encoding == "gz") {
    // Inflates what teem will (byte skip and voxels, then the stream's end),
    // never more: a small file can expand without bound.
    if (std::fflush(f) != 0 || lseek(fileno(f), off_t(start), SEEK_SET) != off_t(start)) return "cannot read the data";
    const int gz_fd = dup(fileno(f));
    gzFile z = gz_fd < 0 ? nullptr : gzdopen(gz_fd, "rb");
    if (!z) {
      if (gz_fd >= 0) close(gz_fd);
      return "cannot read the data";
    }
    struct GzClose {
      gzFile z;
      ~GzClose() { gzclose(z); }
    } gz_closer{z};
    std::vector<char> buffer(1 << 20);
    std::int64_t want = byte_skip + expected + 1, total = 0;
    for (int n = 1; total < want && n > 0; total += n) {
      n = gzread(z, buffer.data(), unsigned(std::min<std::int64_t>(std::int64_t(buffer.size()), want - total)));
      if (n < 0) break;
    }
    int err = Z_OK;
    std::string message = gzerror(z, &err);
    // zlib names the descriptor ("<fd:5>: "): keep only what is wrong.
    if (const auto colon = message.find(">: "); message.rfind("<fd:", 0) == 0 && colon != std::string::npos) {
      message = message.substr(colon + 3);
    }
    if (err != Z_OK && err != Z_STREAM_END) return fmt::format("compressed data are damaged ({})", message);
    if (total < byte_skip + expected) {
      return fmt::format("truncated: {} voxel bytes expected, the compressed data hold {}", expected,
                         std::max<std::int64_t>(0, total - byte_skip));
    }
    return "";
  }
  const bool hex = encoding == "hex";
  if (!hex && encoding != "ascii" && encoding != "text" && encoding != "txt") return "";
  if (byte_skip != 0) return fmt::format("'byte skip' is for raw and compressed data, not '{}'", encoding);
  // ASCII: one number per blank-separated token; hex: two digits per byte.
  const int component = int(io.GetComponentSize());
  const std::int64_t wanted = hex ? 2 * expected : expected / std::max(1, component);
  const bool integral = io.GetComponentType() != itk::IOComponentEnum::FLOAT &&
                        io.GetComponentType() != itk::IOComponentEnum::DOUBLE;
  std::int64_t found = 0;
  std::string token;
  auto number = [&](const std::string& t) {
    if (t.size() > 256) return false;
    char* end = nullptr;
    if (integral) {
      std::strtoll(t.c_str(), &end, 10);
    } else {
      std::strtod(t.c_str(), &end);
    }
    return end != t.c_str();
  };
  for (int c = std::getc(f); found < wanted; c = std::getc(f)) {
    if (hex) {
      if (c == EOF) break;
      if (std::isxdigit(c)) {
        ++found;
      } else if (!std::isspace(c)) {
        return fmt::format("hex data hold '{}' where a digit belongs", char(c));
      }
      continue;
    }
    if (c != EOF && !std::isspace(c)) {
      if (token.size() <= 256) token += char(c);
      continue;
    }
    if (!token.empty()) {
      if (!number(token)) return fmt::format("ASCII data hold '{}' where a number belongs", token.substr(0, 32));
      ++found;
      token.clear();
    }
    if (c == EOF) break;
  }
  if (found < wanted) {
    return fmt::format("truncated: {} {} expected, {} holds {}", wanted, hex ? "hex digits" : "values",
                       shown_data, found);
  }
  return "";
}

bool IsGzipped(const fs::path& path) {
  std::string name = path.filename().string();
  for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
  return name.ends_with(".nrrd.gz");
}

// A whole NRRD file gzipped (.nrrd.gz): teem inflates gzip only as a NRRD's
// encoding of its voxels. So the header, read through zlib, is rewritten as a
// detached header that names the file itself as its data, gzip-encoded, with
// a byte skip past the header: teem inflates the file and skips what the
// header took.
std::string GzippedRewrite(const fs::path& path, const std::string& shown) {
  const int fd = file_checks::OpenRegularFile(path);
  gzFile z = fd < 0 ? nullptr : gzdopen(fd, "rb");
  if (!z) {
    if (fd >= 0) close(fd);
    throw InputError(fmt::format("{}: cannot be read", shown));
  }
  std::string text(kMaxHeaderBytes, '\0');
  const int got = gzread(z, text.data(), unsigned(text.size()));
  gzclose(z);
  text.resize(std::size_t(std::max(got, 0)));
  if (text.rfind("NRRD", 0) != 0) throw InputError(fmt::format("{}: not a gzipped NRRD file", shown));
  std::string out;
  std::int64_t byte_skip = 0;
  for (std::size_t line_count = 1;; ++line_count) {
    const std::int64_t end = OffsetAfterLines(text, line_count);
    if (end < 0) throw InputError(fmt::format("{}: the header does not end within {} bytes", shown, text.size()));
    const std::int64_t begin = OffsetAfterLines(text, line_count - 1);
    std::string line = text.substr(std::size_t(begin), std::size_t(end - begin));
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    if (line.empty()) {  // the blank line before the voxels
      out += fmt::format("encoding: gzip\nbyte skip: {}\ndata file: {}\n", end + byte_skip,
                         fs::absolute(path).lexically_normal().string());
      return out;
    }
    const std::string key = FieldName(line);
    const std::string value = TrimBlanks(line.substr(std::min(line.size(), line.find(':') + 1)));
    if (key == "datafile") throw InputError(fmt::format("{}: a gzipped NRRD must hold its voxels itself", shown));
    if (key == "lineskip" && value != "0") throw InputError(fmt::format("{}: 'line skip' in a gzipped NRRD", shown));
    if (key == "encoding" && value != "raw") {
      throw InputError(fmt::format("{}: a gzipped NRRD's voxels must be raw, not '{}'", shown, value.substr(0, 32)));
    }
    if (key == "byteskip") {
      const auto [ptr, ec] = std::from_chars(value.data(), value.data() + value.size(), byte_skip);
      if (ec != std::errc() || byte_skip < 0) throw InputError(fmt::format("{}: 'byte skip' is not a count", shown));
    }
    if (key != "encoding" && key != "byteskip" && key != "lineskip") out += line + "\n";
  }
}

}  // namespace cinevol::formats::nrrd

// What a volume load may open, and the other files a header names.
#include "io/file_checks.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"

namespace fs = std::filesystem;

namespace cinevol::file_checks {
namespace {

// A header naming more files than a volume has slices is not a volume.
constexpr long long kMaxListedFiles = kMaxVoxelsPerAxis;

std::string Lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string Trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

// A field name lower-cased and without blanks, so that "DATA FILE",
// "datafile" and "data  file" compare equal: the check must catch every
// spelling a lenient reader might accept.
std::string NormalKey(const std::string& key) {
  std::string out;
  for (char c : Lower(key)) {
    if (c != ' ' && c != '\t') out += c;
  }
  return out;
}

// Header lines as teem and MetaIO split them: "\n", "\r\n" and a lone "\r"
// each end a line, and a NUL ends what a C reader sees of one.
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

// Adds a file a header names; relative names are relative to the header's
// folder in every format cinevol reads. "-" is standard input to teem.
void AddFile(References& refs, const fs::path& dir, const std::string& name) {
  if (name == "-") {
    refs.files.push_back("/dev/stdin");
  } else {
    refs.files.push_back(!name.empty() && name[0] == '/' ? fs::path(name) : dir / name);
  }
}

// "name%03d.raw <min> <max> <step> [<dim>]". The readers hand the name to
// sprintf, so only a single %d with an optional 0 flag and width is accepted.
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

// Every non-empty line from `first` on names a file (a LIST).
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

// NIfTI pairs and Analyze keep the voxels in an .img beside the .hdr, and the
// readers find one from the other by name: every such sibling counts.
References PairReferences(const fs::path& file) {
  References refs{"NIfTI/Analyze .hdr/.img pair", {}, ""};
  std::string base = file.filename().string();
  if (EndsWith(Lower(base), ".gz")) base.resize(base.size() - 3);
  base.resize(base.size() - std::min<std::size_t>(base.size(), 4));  // .hdr .img .nii .nia
  for (const char* ext : {".hdr", ".HDR", ".hdr.gz", ".HDR.gz", ".img", ".IMG", ".img.gz", ".IMG.gz", ".nii",
                          ".nii.gz"}) {
    const fs::path sibling = file.parent_path() / (base + ext);
    std::error_code ec;
    if (sibling != file && fs::exists(fs::symlink_status(sibling, ec))) refs.files.push_back(sibling);
  }
  return refs;
}

// A single-file NIfTI ("n+1", "n+2" magic) holds its voxels; "ni1"/"ni2" and
// Analyze headers name an .img. The header is read through zlib (.nii.gz).
References NiftiReferences(const fs::path& file) {
  const int fd = OpenRegularFile(file);
  if (fd < 0) return {};
  gzFile f = gzdopen(fd, "rb");
  if (!f) {
    close(fd);
    return {};
  }
  char h[348] = {};
  const int n = gzread(f, h, sizeof h);
  gzclose(f);
  std::int32_t size = 0;
  std::memcpy(&size, h, sizeof size);
  const std::int32_t swapped = std::int32_t(__builtin_bswap32(std::uint32_t(size)));
  if (n >= 8 && (size == 540 || swapped == 540)) {
    return std::memcmp(h + 4, "n+2", 4) == 0 ? References{} : PairReferences(file);
  }
  if (n >= 8 && (size == 348 || swapped == 348)) {
    return n == 348 && std::memcmp(h + 344, "n+1", 4) == 0 ? References{} : PairReferences(file);
  }
  return {};
}

// MetaImage: "ElementDataFile = LOCAL" (voxels follow), a file, "LIST" (file
// names follow), or a pattern. It is the header's last field.
References MetaImageReferences(const fs::path& file, const std::string& head) {
  const bool truncated = head.size() > kMaxHeaderBytes;
  const std::vector<std::string> lines = Lines(head);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::size_t sep = lines[i].find_first_of("=:");
    if (sep == std::string::npos || NormalKey(lines[i].substr(0, sep)) != "elementdatafile") continue;
    const std::string value = Trim(lines[i].substr(sep + 1));
    if (value == "LOCAL" || value == "Local" || value == "local") return {};
    References refs{"ElementDataFile", {}, ""};
    if (value.rfind("LIST", 0) == 0) {
      AddList(refs, file.parent_path(), lines, i + 1, truncated);
    } else if (value.find('%') != std::string::npos) {
      AddPattern(refs, file.parent_path(), value, nullptr);
    } else {
      AddFile(refs, file.parent_path(), value);
    }
    return refs;
  }
  if (!truncated) return {};
  return {"", {}, fmt::format("a header longer than {} bytes", kMaxHeaderBytes)};
}

}  // namespace

std::string Shown(const fs::path& path, const LoadPolicy& policy) {
  return policy.label.empty() ? path.string() : policy.label;
}

bool IsRegularFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(fs::status(path, ec));
}

void RequireRegularFile(const fs::path& path, const std::string& shown) {
  if (!IsRegularFile(path)) throw InputError(fmt::format("{}: not a regular file", shown));
}

int OpenRegularFile(const fs::path& path) {
  if (!IsRegularFile(path)) return -1;  // opening a device can have effects of its own
  const int fd = open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  struct stat st;
  if (fd >= 0 && (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))) {
    close(fd);
    return -1;
  }
  return fd;
}

FileStream OpenRegularStream(const fs::path& path) {
  const int fd = OpenRegularFile(path);
  std::FILE* f = fd < 0 ? nullptr : fdopen(fd, "rb");
  if (!f && fd >= 0) close(fd);
  return {f, &std::fclose};
}

std::string ReadHead(const fs::path& path, std::size_t limit, const std::string& shown) {
  const int fd = OpenRegularFile(path);
  if (fd < 0) throw InputError(fmt::format("{}: not a regular file that can be read", shown));
  std::string text(limit, '\0');
  std::size_t got = 0;
  for (ssize_t n; got < limit && (n = read(fd, text.data() + got, limit - got)) > 0;) got += std::size_t(n);
  close(fd);
  text.resize(got);
  return text;
}

bool IsInside(const fs::path& path, const std::vector<fs::path>& roots) {
  return std::any_of(roots.begin(), roots.end(), [&](const fs::path& given) {
    std::error_code ec;
    const fs::path root = fs::weakly_canonical(given, ec);  // in case a caller's is not
    return !ec && !root.empty() &&
           std::mismatch(root.begin(), root.end(), path.begin(), path.end()).first == root.end();
  });
}

void RequireInsideRoots(const fs::path& path, const LoadPolicy& policy, const std::string& shown) {
  if (policy.references != LoadPolicy::References::kInsideRoots) return;
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  if (ec || !IsInside(real, policy.roots)) throw InputError(fmt::format("{}: outside the data roots", shown));
}

std::string FieldName(const std::string& line) {
  const std::size_t colon = line.find(':');
  return line.empty() || line[0] == '#' || colon == std::string::npos ? "" : NormalKey(line.substr(0, colon));
}

NrrdHeader ParseNrrdHeader(const fs::path& file, const std::string& shown) {
  const std::string head = ReadHead(file, kMaxHeaderBytes + 1, shown);
  const bool truncated = head.size() > kMaxHeaderBytes;
  const std::vector<std::string> lines = Lines(head);
  NrrdHeader h;
  bool ended = false;
  std::size_t i = 0;
  for (; i < lines.size() && !ended; ++i) {
    const std::string& line = lines[i];
    ended = i > 0 && line.empty();  // the blank line before attached voxels
    // teem: the field name is what precedes ": ", and '#' starts a comment.
    if (i == 0 || ended || FieldName(line) != "datafile") {
      if (!ended) h.lines.push_back(line);
      continue;
    }
    const std::size_t colon = line.find(':');
    const std::string value = line.substr(std::min(line.size(), line.find_first_not_of(" \t", colon + 1)));
    h.attached = false;
    h.references.field = "data file";
    h.listed = value.rfind("LIST", 0) == 0 || value.find('%') != std::string::npos;
    if (value.rfind("LIST", 0) == 0) {
      h.list_dim = Trim(value.substr(4));
      AddList(h.references, file.parent_path(), lines, i + 1, truncated);
      return h;  // the list runs to the end of the file
    } else if (value.find('%') != std::string::npos) {
      AddPattern(h.references, file.parent_path(), value, &h.list_dim);
    } else {
      AddFile(h.references, file.parent_path(), value);
    }
  }
  h.line_count = i;
  if (!ended && truncated) {
    h.references.problem = fmt::format("a header longer than {} bytes", kMaxHeaderBytes);
  }
  return h;
}

References FindReferences(const fs::path& file, const std::string& shown) {
  const std::string name = Lower(file.filename().string());
  for (const char* ext : {".hdr", ".img", ".hdr.gz", ".img.gz"}) {
    if (EndsWith(name, ext)) return PairReferences(file);
  }
  if (EndsWith(name, ".nii") || EndsWith(name, ".nii.gz") || EndsWith(name, ".nia")) return NiftiReferences(file);
  if (EndsWith(name, ".mha") || EndsWith(name, ".mhd")) {
    return MetaImageReferences(file, ReadHead(file, kMaxHeaderBytes + 1, shown));
  }
  // teem reads any file that starts with the magic, whatever the name says.
  if (ReadHead(file, 4, shown) == "NRRD") return ParseNrrdHeader(file, shown).references;
  return {};
}

void CheckReferences(const References& refs, const LoadPolicy& policy, const std::string& shown) {
  using R = LoadPolicy::References;
  if (refs.field.empty()) {
    if (!refs.problem.empty() && policy.references != R::kAnywhere) {
      throw InputError(fmt::format("{}: {}", shown, refs.problem));
    }
    return;
  }
  if (policy.references == R::kNone) {
    throw InputError(fmt::format("{}: the header names another file ('{}'); uploads must be self-contained",
                                 shown, refs.field));
  }
  if (policy.references == R::kAnywhere) {
    // The operator's own files may name any file, but only a regular one: a
    // FIFO blocks the reader, a device never ends. A missing one ITK reports.
    for (const fs::path& file : refs.files) {
      std::error_code ec;
      if (fs::exists(fs::status(file, ec)) && !IsRegularFile(file)) {
        throw InputError(fmt::format("{}: the header's '{}' names something other than a regular file", shown,
                                     refs.field));
      }
    }
    return;
  }
  if (!refs.problem.empty()) {
    throw InputError(fmt::format("{}: the header's '{}' cannot be checked: {}", shown, refs.field, refs.problem));
  }
  for (const fs::path& file : refs.files) {
    // One message for missing, outside and irregular files: it must not
    // tell whether a file outside the roots exists.
    std::error_code ec;
    const fs::path real = fs::canonical(file, ec);
    if (ec || !IsInside(real, policy.roots) || !IsRegularFile(real)) {
      throw InputError(fmt::format(
          "{}: the header's '{}' names a file that is not a regular file inside the data roots", shown,
          refs.field));
    }
  }
}

}  // namespace cinevol::file_checks

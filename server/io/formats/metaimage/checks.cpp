// What stands in front of MetaIO inside the cage: header text, payload, the
// rewrite that names placed files, and the data file MetaIO settled on.
#include "io/formats/metaimage/checks.h"

#include <itkMetaImageIO.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/formats/header_text.h"
#include "io/formats/metaimage/references.h"
#include "io/formats/payload.h"

namespace fs = std::filesystem;

namespace cinevol::formats::metaimage {
namespace {

// The MetaImage header as MetaIO reads it: "Key = value" lines, the last
// ElementDataFile; LOCAL data begin right after that line.
struct Fields {
  std::int64_t data_start = -1;        // -1: no ElementDataFile line found
  std::int64_t header_size = 0;        // HeaderSize: bytes skipped before the data
  double compressed_size = -1;         // CompressedDataSize; -1 when absent
};

Fields ReadFields(const fs::path& path, const std::string& shown) {
  const std::string head = file_checks::ReadHead(path, kMaxHeaderBytes, shown);
  Fields h;
  for (std::size_t pos = 0; pos < head.size();) {
    const std::size_t end = std::min(head.find('\n', pos), head.size());
    const std::string line = head.substr(pos, end - pos);
    pos = std::min(end + 1, head.size());
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = TrimBlanks(line.substr(0, eq)), value = TrimBlanks(line.substr(eq + 1));
    if (key == "CompressedDataSize") {
      h.compressed_size = std::strtod(value.c_str(), nullptr);
    } else if (key == "HeaderSize") {
      h.header_size = std::strtoll(value.c_str(), nullptr, 10);
    } else if (key == "ElementDataFile") {
      h.data_start = std::int64_t(pos);
      break;
    }
  }
  return h;
}

}  // namespace

bool StatesOrientation(const fs::path& path, const std::string& shown) {
  const std::string head = file_checks::ReadHead(path, kMaxHeaderBytes, shown);
  for (const std::string& line : Lines(head)) {
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = TrimBlanks(line.substr(0, eq));
    if (key == "TransformMatrix" || key == "Orientation" || key == "Rotation") return true;
    if (key == "ElementDataFile") break;
  }
  return false;
}

namespace {

// MetaIO's own reading of a header's fields (CompressedDataSize has no
// accessor: a pointer to the protected member, named through a derived class).
struct MetaFields : MetaImage {
  static std::streamoff CompressedDataSize(const MetaImage& m) { return m.*(&MetaFields::m_CompressedDataSize); }
};

// Where MetaIO finds LOCAL data: just past the header as MetaIO itself reads
// it (the same parse ITK's reader makes before reading the voxels); -1 when
// it cannot tell.
std::int64_t LocalDataStart(const fs::path& path) {
  std::ifstream stream(path, std::ios::in | std::ios::binary);
  if (!stream) return -1;
  MetaImage header;
  if (!header.ReadStream(0, &stream, false)) return -1;
  const std::streampos at = stream.tellg();
  return at == std::streampos(-1) ? -1 : std::int64_t(at);
}

// MetaIO inflates a compressed payload without checking what zlib says:
// damaged or short data load as whatever the buffer held, and its streamed
// reading returns on a zlib error without freeing its buffers (a leak per
// load). So the payload is inflated here first, as MetaIO will read it: the
// `length` bytes of `data` from `start`, up to the voxels' `expected` bytes
// (and one more, to see a stream longer than the image), never beyond.
// Returns "" when the stream holds every voxel, else what is wrong.
std::string CompressedProblem(const fs::path& data, std::int64_t start, std::int64_t length, std::int64_t expected,
                              const std::string& shown_data) {
  const file_checks::FileStream stream = file_checks::OpenRegularStream(data);
  if (!stream) return "cannot read the file that ElementDataFile names";
  std::FILE* f = stream.get();
  if (std::fseek(f, long(start), SEEK_SET) != 0) return "cannot read the data";
  z_stream z{};
  // 47: zlib or gzip headers, as MetaIO inflates.
  if (inflateInit2(&z, 47) != Z_OK) return "cannot inflate the compressed data";
  struct End {
    z_stream* z;
    ~End() { inflateEnd(z); }
  } ender{&z};
  std::vector<unsigned char> in(std::size_t{1} << 16), out(std::size_t{1} << 20);
  std::int64_t unread = length, total = 0;
  int ret = Z_OK;
  while (total <= expected) {
    if (z.avail_in == 0 && unread > 0) {
      const std::size_t want = std::size_t(std::min<std::int64_t>(std::int64_t(in.size()), unread));
      const std::size_t n = std::fread(in.data(), 1, want, f);
      if (n == 0) break;
      unread -= std::int64_t(n);
      z.next_in = in.data();
      z.avail_in = uInt(n);
    }
    const uInt room = uInt(std::min<std::int64_t>(std::int64_t(out.size()), expected + 1 - total));
    z.next_out = out.data();
    z.avail_out = room;
    ret = inflate(&z, Z_NO_FLUSH);
    total += std::int64_t(room - z.avail_out);
    if (ret == Z_STREAM_END || ret == Z_BUF_ERROR) break;  // the stream's end, or its input's
    if (ret != Z_OK) {
      return fmt::format("compressed data are damaged ({})",
                         ret == Z_NEED_DICT ? "a preset dictionary is needed" : z.msg ? z.msg : zError(ret));
    }
  }
  if (total < expected) {
    return fmt::format("truncated: {} voxel bytes expected, the compressed data in {} hold {}", expected,
                       shown_data == "the file after its header" ? "the file" : shown_data, total);
  }
  if (total > expected) {
    return fmt::format("compressed data are damaged (they hold more than the {} voxel bytes expected)", expected);
  }
  return "";
}

}  // namespace

// The header as MetaIO walks it, up to its ElementDataFile line, with what
// fuzz_volume found MetaIO does with each kind of line:
// - It copies each key it reads (up to 500 characters, up to '=', ':' or a
//   line end) into a 255-byte field name: a longer run overflows it (an abort
//   under _FORTIFY_SOURCE). A run can start anywhere (the rest of a value
//   MetaIO did not take is read as the next key), so no run may reach 255.
// - A line with no '=' or ':' is a key whose value MetaIO looks for on the
//   lines after: the next line, an ElementDataFile one included, is eaten as
//   that value, and MetaIO reads the binary data on as header.
// - It reads NDims values for DimSize and the like (NDims squared for a
//   matrix) into arrays of 10 (100): a negative or large NDims made it loop
//   for hours or write past them.
// The walk ends at the first line whose key is ElementDataFile, as MetaIO's
// does (not at the name inside a value).
void CheckHeaderText(const fs::path& path, const std::string& shown) {
  const std::string head = file_checks::ReadHead(path, kMaxHeaderBytes, shown);
  constexpr std::size_t kMaxRun = 254;
  int line_number = 0;
  for (std::size_t pos = 0; pos < head.size();) {
    const std::size_t line_end = std::min(head.find_first_of("\r\n", pos), head.size());
    const std::string line = head.substr(pos, line_end - pos);
    pos = line_end + 1;
    ++line_number;
    const std::size_t sep = line.find_first_of("=:");
    if (sep == std::string::npos) {
      if (line.find_first_not_of(" \t") == std::string::npos) continue;  // blank: MetaIO skips it
      throw InputError(fmt::format("{}: header line {} holds no '=' (MetaIO would take the next line as its value)",
                                   shown, line_number));
    }
    std::size_t run = 0;
    for (const char c : line) {
      run = (c == '=' || c == ':') ? 0 : run + 1;
      if (run > kMaxRun) {
        throw InputError(
            fmt::format("{}: a header line holds more than {} characters between separators", shown, kMaxRun));
      }
    }
    const std::string key = TrimBlanks(line.substr(0, sep));
    if (key == "NDims") {
      const std::string value = TrimBlanks(line.substr(sep + 1));
      char* stop = nullptr;
      const double n = std::strtod(value.c_str(), &stop);
      if (stop == value.c_str() || !(n >= 1 && n <= 10) || n != std::floor(n)) {
        throw InputError(fmt::format("{}: NDims '{}' is not a dimension count (1 to 10)", shown, value.substr(0, 32)));
      }
    }
    if (key == "ElementDataFile") return;
  }
}

// A MetaImage header whose ElementDataFile names where the cage placed the
// files (`named`, in the header's order): a single file, or a LIST.
std::string RewrittenHeader(const fs::path& header, const std::vector<fs::path>& named, const std::string& shown) {
  const std::string head = file_checks::ReadHead(header, kMaxHeaderBytes, shown);
  std::string out;
  for (std::size_t pos = 0; pos < head.size();) {
    const std::size_t end = std::min(head.find_first_of("\r\n", pos), head.size());
    const std::string line = head.substr(pos, end - pos);
    pos = end + 1;
    const std::size_t sep = line.find_first_of("=:");
    std::string key = sep == std::string::npos ? "" : line.substr(0, sep);
    key.erase(std::remove_if(key.begin(), key.end(), [](char c) { return c == ' ' || c == '\t'; }), key.end());
    if (key != "ElementDataFile") {
      out += line + "\n";
      continue;
    }
    // A LIST's or pattern's file dimension, when the header gives one.
    std::string dim;
    const std::string value = line.substr(sep + 1);
    if (const auto list = value.find("LIST"); list != std::string::npos) {
      std::istringstream in(value.substr(list + 4));
      in >> dim;
    } else if (value.find('%') != std::string::npos) {
      std::istringstream in(value);
      std::string format, lo, hi, step;
      in >> format >> lo >> hi >> step >> dim;
      if (!dim.empty()) dim += "D";
    }
    if (named.size() == 1 && value.find("LIST") == std::string::npos && value.find('%') == std::string::npos) {
      out += "ElementDataFile = " + fs::absolute(named[0]).lexically_normal().string() + "\n";
    } else {
      out += "ElementDataFile = LIST" + (dim.empty() ? "" : " " + dim) + "\n";
      for (const fs::path& f : named) out += fs::absolute(f).lexically_normal().string() + "\n";
    }
    return out;
  }
  throw InputError(fmt::format("{}: the header changed while it was read", shown));
}

// ITK's MetaImage reader warns about a short payload on stderr and carries
// on. For uncompressed data the file that holds the voxels must be at least
// as long as they are (a LOCAL MetaImage's header not counted), and
// compressed data no longer than the file: MetaIO allocates what
// CompressedDataSize says before reading.
std::string PayloadProblem(itk::ImageIOBase& io, const fs::path& path, const std::string& shown) {
  auto* meta = dynamic_cast<itk::MetaImageIO*>(&io);
  if (!meta) return "";
  const std::string file = meta->GetMetaImagePointer()->ElementDataFileName();
  if (file == "LIST" || file.find('%') != std::string::npos || file.find(' ') != std::string::npos) return "";
  const bool local = IsLocal(file);
  const fs::path data = local ? path : fs::path(file).is_absolute() ? fs::path(file) : path.parent_path() / file;
  const Fields h = ReadFields(path, shown);
  // Bytes of `data` before the voxels: a LOCAL MetaImage's header, HeaderSize.
  std::int64_t skip = (local ? std::max<std::int64_t>(0, h.data_start) : 0) + std::max<std::int64_t>(0, h.header_size);
  const MetaImage& image = *meta->GetMetaImagePointer();
  if (image.CompressedData()) {
    // MetaIO reads compressed data from just past the header (LOCAL) or the
    // data file's start; it skips no HeaderSize the same way on every path.
    if (image.HeaderSize() != 0) return "'HeaderSize' is for uncompressed data only";
    const std::int64_t start = local ? LocalDataStart(path) : 0;
    if (start < 0) return "cannot find where the compressed data begin";
    std::error_code ec;
    const std::int64_t size = file_checks::IsRegularFile(data) ? std::int64_t(fs::file_size(data, ec)) : 0;
    if (ec || !file_checks::IsRegularFile(data)) return "cannot read the file that ElementDataFile names";
    const std::string shown_data = local ? "the file after its header" : fmt::format("'{}'", data.filename().string());
    // MetaIO allocates CompressedDataSize bytes before it reads them; 0
    // (or none given) means the rest of the file.
    const std::int64_t declared = MetaFields::CompressedDataSize(image);
    if (declared < 0) return fmt::format("CompressedDataSize {} is negative", declared);
    if (!(h.compressed_size <= double(size - start)) || declared > size - start) {
      return fmt::format("CompressedDataSize {} is more than {} holds ({} bytes)",
                         std::max(h.compressed_size, double(declared)), shown_data,
                         std::max<std::int64_t>(0, size - start));
    }
    return CompressedProblem(data, start, declared > 0 ? declared : size - start,
                             std::int64_t(io.GetImageSizeInBytes()), shown_data);
  }
  if (h.header_size < 0) skip = 0;  // HeaderSize -1: the voxels are the file's last bytes
  return UncompressedPayloadProblem(data, path, skip, std::int64_t(io.GetImageSizeInBytes()));
}

std::string Modality(itk::ImageIOBase& io) {
  auto* meta = dynamic_cast<itk::MetaImageIO*>(&io);
  if (!meta) return "";
  switch (meta->GetMetaImagePointer()->Modality()) {
    case MET_MOD_CT: return "CT";
    case MET_MOD_MR: return "MR";
    default: return "";
  }
}

// MetaIO parsed the header on its own: what it will open must be where the
// cage placed the files (or the file itself, LOCAL). A list or pattern was
// rewritten to the placed files before MetaIO saw it.
void CheckDataFile(itk::ImageIOBase& io, const fs::path& path, const std::vector<fs::path>& placed,
                   const std::string& shown) {
  auto* meta = dynamic_cast<itk::MetaImageIO*>(&io);
  if (!meta) return;
  const std::string name = meta->GetMetaImagePointer()->ElementDataFileName();
  if (IsLocal(name)) return;
  const bool listed = name.rfind("LIST", 0) == 0 || name.find('%') != std::string::npos;
  const fs::path file =
      (!name.empty() && name[0] == '/' ? fs::path(name) : path.parent_path() / name).lexically_normal();
  const bool seen = std::any_of(placed.begin(), placed.end(), [&](const fs::path& p) {
    return fs::absolute(p).lexically_normal() == fs::absolute(file).lexically_normal();
  });
  if ((listed && placed.empty()) || (!listed && !seen)) {
    throw InputError(fmt::format("{}: the header's 'ElementDataFile' names a file the header check did not see",
                                 shown));
  }
}

}  // namespace cinevol::formats::metaimage

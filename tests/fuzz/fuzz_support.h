// What the reader fuzz targets share: a scratch folder, fresh input and work
// folders per input, and requests as the reader cage's parent would send.
#pragma once

#include <stdlib.h>

#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "cinevol/reader/reader.pb.h"
#include "core/volume.h"
#include "core/voxel_memory.h"
#include "io/file_checks.h"
#include "io/reader_channel.h"
#include "io/readers/reading.h"

namespace cinevol::fuzz {

// A temporary folder, removed at exit; each input gets an empty folder for
// its files and another for the reader's links (reader::Job needs one).
class Scratch {
 public:
  explicit Scratch(const char* prefix) {
    std::string pattern = (std::filesystem::temp_directory_path() / (std::string(prefix) + "-XXXXXX")).string();
    if (!mkdtemp(pattern.data())) std::abort();
    root_ = pattern;
  }
  ~Scratch() {
    std::error_code ec;
    std::filesystem::remove_all(root_, ec);
  }
  std::filesystem::path FreshInputDir() { return Fresh("in"); }
  std::filesystem::path FreshWorkDir() { return Fresh("work"); }

 private:
  std::filesystem::path Fresh(const char* name) {
    const std::filesystem::path dir = root_ / name;
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    if (!std::filesystem::create_directory(dir, ec)) std::abort();
    return dir;
  }
  std::filesystem::path root_;
};

// CINEVOL_READER_PRECHECKS=off: the readers' pre-checks skipped, as the
// server does with the same variable.
inline bool PrechecksOff() {
  const char* v = std::getenv("CINEVOL_READER_PRECHECKS");
  return v && std::string_view(v) == "off";
}

inline reader::Request BaseRequest(reader::Request::Kind kind, const std::string& shown, std::uint64_t max_voxels) {
  reader::Request r;
  r.set_kind(kind);
  r.set_shown(shown);
  r.set_max_voxels(max_voxels);
  r.set_skip_prechecks(PrechecksOff());
  return r;
}

inline void WriteFile(const std::filesystem::path& path, const void* data, std::size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  const bool ok = size == 0 || std::fwrite(data, 1, size, f) == size;
  if (std::fclose(f) != 0 || !ok) std::abort();
}

// The input's descriptor, opened as the parent opens it.
inline UniqueFd OpenInput(const std::filesystem::path& path) {
  UniqueFd fd(file_checks::OpenRegularFile(path));
  if (!fd) std::abort();
  return fd;
}

// A header the parent takes (io/reader_cage.cpp, Check): three dimensions
// within the axis limit, finite geometry, a known voxel type, short texts.
// Anything else is a broken protocol there ("sent a header that does not
// hold together") instead of the reader's refusal. Aborts then.
inline void RequireSaneHeader(const reader::Reply& reply) {
  if (!reply.has_header()) return;
  const reader::Header& h = reply.header();
  auto finite = [](const auto& values, int count) {
    if (values.size() != count) return false;
    for (double v : values) {
      if (!std::isfinite(v)) return false;
    }
    return true;
  };
  bool sane = h.dims_size() == 3 && finite(h.spacing_mm(), 3) && finite(h.origin_mm(), 3) &&
              finite(h.direction(), 9) && VoxelTypeNamed(h.voxel_type()) && h.modality().size() <= 64 &&
              h.value_unit().size() <= 64 && h.original_type().size() <= 256;
  for (int a = 0; sane && a < 3; ++a) sane = h.dims(a) >= 1 && h.dims(a) <= std::uint32_t(kMaxVoxelsPerAxis);
  if (!sane) {
    std::fprintf(stderr, "the reader's header would be a broken protocol to the parent: %s\n",
                 h.ShortDebugString().c_str());
    std::abort();
  }
}

// The child's answer travels to the parent as a protobuf message: one that
// does not parse back (a proto3 string holding bytes that are not UTF-8)
// reaches the parent as a broken protocol instead of the answer. Aborts then.
inline void RequireWireForm(const reader::Reply& reply) {
  RequireSaneHeader(reply);
  reader::Reply back;
  if (!back.ParseFromString(reply.SerializeAsString())) {
    std::fprintf(stderr, "the reader's answer does not survive the socket (not UTF-8?): %s\n",
                 reply.ShortDebugString().c_str());
    std::abort();
  }
}

// The same for a refusal, as cinevol-reader sends an exception's message.
inline void RequireFailureWireForm(const std::string& message) {
  reader::Reply reply;
  reply.mutable_failure()->set_kind(reader::Failure::INPUT);
  reply.mutable_failure()->set_message(message);
  RequireWireForm(reply);
}

// What cinevol-reader does with a request (reader_main.cpp, Serve), in this
// process: the answer, checked as the parent would check it, then the voxels
// into memory of the size the header announces (reader::ReadInProcess does
// the same without the check between).
inline void ReadLikeTheChild(const reader::Request& request, std::vector<UniqueFd> inputs) {
  reader::Job job(request, std::move(inputs));
  const reader::Reply reply = job.Answer();
  RequireWireForm(reply);
  if (!reply.has_header()) return;
  const reader::Header& h = reply.header();
  const std::uint64_t voxels = std::uint64_t(h.dims(0)) * h.dims(1) * h.dims(2);
  if (voxels > request.max_voxels()) throw std::runtime_error("the parent refuses the header: too many voxels");
  std::vector<unsigned char> memory(voxels * BytesPerVoxel(*VoxelTypeNamed(h.voxel_type())));
  job.Write(memory.data(), memory.size());
}

// CINEVOL_FUZZ_VERBOSE=1: each input's outcome on stderr (to check seeds and reproducers).
inline void Verbose(const char* format, ...) {
  static const bool verbose = std::getenv("CINEVOL_FUZZ_VERBOSE") != nullptr;
  if (!verbose) return;
  va_list args;
  va_start(args, format);
  std::vfprintf(stderr, format, args);
  va_end(args);
}

}  // namespace cinevol::fuzz

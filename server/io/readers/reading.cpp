// Job: one request inside the cage, from its inputs to its answer.
#include "io/readers/reading.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <new>

#include <fmt/format.h>

#include "core/error.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "io/formats/format.h"
#include "io/label_volume.h"
#include "io/readers/seg_reader.h"
#include "io/readers/volume_read.h"

namespace fs = std::filesystem;

namespace cinevol::reader {
namespace {

// A name that can be a file name in the work folder: the last part of
// `name`, "input" when that is empty or a dot name.
std::string SafeFileName(const std::string& name) {
  std::string last = fs::path(name).filename().string();
  if (last.empty() || last == "." || last == "..") last = "input";
  return last;
}

// The extension a reader needs to see ("" when the name has none it knows).
std::string Extension(const std::string& name) {
  if (std::string ending = formats::KnownEnding(name); !ending.empty()) return ending;
  std::string lower = name;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  return lower.ends_with(".exr") ? name.substr(name.size() - 4) : "";
}

// The file a rewritten header goes to: named as a reader of the main file's
// format expects (a gzipped NRRD's becomes a detached header).
std::string ScratchName(const std::string& main) {
  const std::string ext = Extension(main);
  return "rewritten" + (ext == ".nrrd.gz" ? std::string(".nhdr") : ext);
}

std::string DescriptorPath(int fd) { return fmt::format("/proc/self/fd/{}", fd); }

// At most `limit` bytes from the start of `fd`.
std::string ReadAll(int fd, std::size_t limit) {
  std::string text(limit, '\0');
  std::size_t got = 0;
  for (ssize_t n; got < limit && (n = pread(fd, text.data() + got, limit - got, off_t(got))) > 0;)
    got += std::size_t(n);
  text.resize(got);
  return text;
}

void Link(const std::string& target, const fs::path& link) {
  if (symlink(target.c_str(), link.c_str()) != 0) {
    throw std::runtime_error(fmt::format("cannot place a link in the reader's folder ({})", std::strerror(errno)));
  }
}

}  // namespace

Job::Job(Request request, std::vector<UniqueFd> inputs) : request_(std::move(request)), inputs_(std::move(inputs)) {
  if (inputs_.size() != std::size_t(request_.file_names_size()) || inputs_.empty()) {
    throw std::runtime_error("a request whose files did not all come");
  }
  if (request_.kind() != Request::VOLUME) return;  // the others open their inputs by descriptor
  // The file beside the names its header may use, in a folder of its own; any
  // other named file in a folder of its own too (a rewritten header names it).
  const fs::path dir = request_.work_dir();
  const std::string main = SafeFileName(request_.file_names(0));
  Link(DescriptorPath(inputs_[0].get()), dir / main);
  for (std::size_t i = 1; i < inputs_.size(); ++i) {
    const std::string& name = request_.file_names(int(i));
    const std::string file = SafeFileName(name);
    const fs::path own = dir / fmt::format("named-{}", i);
    fs::create_directory(own);
    Link(DescriptorPath(inputs_[i].get()), own / file);
    std::error_code ec;
    if (name == file && file != main && !fs::exists(fs::symlink_status(dir / file, ec))) {
      Link(DescriptorPath(inputs_[i].get()), dir / file);
    }
  }
  scratch_path_ = dir / ScratchName(main);
  scratch_.Reset(open(scratch_path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600));
  if (!scratch_) throw std::runtime_error("cannot make the reader's scratch file");
}

Job::~Job() = default;

std::string Job::InputPath(std::size_t i) const {
  if (request_.kind() != Request::VOLUME) return DescriptorPath(inputs_.at(i).get());
  const fs::path dir = request_.work_dir();
  return (i == 0 ? dir / SafeFileName(request_.file_names(0))
                 : dir / fmt::format("named-{}", i) / SafeFileName(request_.file_names(int(i))))
      .string();
}

Reply Job::Answer() {
  ReadOptions options;
  options.shown = request_.shown();
  options.max_voxels = request_.max_voxels();
  options.prechecks = !request_.skip_prechecks();
  options.resample_uneven = request_.resample_uneven();
  options.scratch_fd = scratch_.get();
  options.scratch_path = scratch_path_;
  std::vector<DicomFile> dicom;
  if (request_.kind() == Request::DICOM_SERIES || request_.kind() == Request::DICOM_LIST ||
      request_.kind() == Request::DICOM_SEG) {
    for (std::size_t i = 0; i < inputs_.size(); ++i) dicom.push_back({InputPath(i), request_.file_names(int(i))});
  }
  Reply reply;
  switch (request_.kind()) {
    case Request::VOLUME: {
      std::vector<fs::path> named;
      for (std::size_t i = 1; i < inputs_.size(); ++i) named.push_back(InputPath(i));
      volume_ = OpenVolumeFile(InputPath(0), named, options);
      *reply.mutable_header() = volume_->header();
      break;
    }
    case Request::DICOM_SERIES:
      volume_ = OpenDicomSeries(dicom, request_.series_uid(), options);
      *reply.mutable_header() = volume_->header();
      break;
    case Request::DICOM_LIST:
      *reply.mutable_series_list() = ListDicomSeries(dicom, options);
      break;
    case Request::DICOM_SEG:
      volume_ = OpenSegmentation(dicom, request_.target(), options);
      *reply.mutable_header() = volume_->header();
      break;
    case Request::LABEL_TABLE: {  // read through its descriptor: an upload's table is a memfd
      const std::string text = ReadAll(inputs_[0].get(), kMaxLabelTableBytes + 1);
      if (text.size() > kMaxLabelTableBytes) {
        throw InputError(fmt::format("{}: a label table may have at most {} bytes", options.shown,
                                     kMaxLabelTableBytes));
      }
      reply.mutable_label_table();  // an empty table is an answer too
      for (const auto& [value, name] : ParseLabelTable(text, options.shown)) {
        (*reply.mutable_label_table()->mutable_names())[value] = name;
      }
      break;
    }
    case Request::EXR_IMAGE: {
      const ImageRgbF image = ReadExr(InputPath(0), options.shown);
      reply.mutable_image()->set_width(std::uint32_t(image.width));
      reply.mutable_image()->set_height(std::uint32_t(image.height));
      pixels_.resize(image.pixels.size() * 3);
      std::memcpy(pixels_.data(), image.pixels.data(), pixels_.size() * sizeof(float));
      break;
    }
    default:
      throw std::runtime_error("a request of no known kind");
  }
  return reply;
}

void Job::Write(void* memory, std::size_t bytes, int phase) {
  if (volume_) {
    if (phase < 0 || phase >= volume_->phases()) throw std::runtime_error("a phase the header did not announce");
    volume_->Read(memory, bytes, phase);
    return;
  }
  if (bytes != pixels_.size() * sizeof(float)) throw std::runtime_error("memory of the wrong size for the image");
  std::memcpy(memory, pixels_.data(), bytes);
}

Reply ReadInProcess(const Request& request, std::vector<UniqueFd> inputs, std::vector<unsigned char>& memory) {
  Job job(request, std::move(inputs));
  Reply reply = job.Answer();
  std::uint64_t bytes = 0;
  int phases = 1;
  if (reply.has_header()) {
    const Header& h = reply.header();
    const auto type = VoxelTypeNamed(h.voxel_type());
    if (!type || h.dims_size() != 3) throw std::runtime_error("a header that does not hold together");
    bytes = std::uint64_t(h.dims(0)) * h.dims(1) * h.dims(2) * BytesPerVoxel(*type);
    phases = std::max<int>(1, int(h.phases()));
  } else if (reply.has_image()) {
    bytes = std::uint64_t(reply.image().width()) * reply.image().height() * 3 * sizeof(float);
  } else {
    return reply;
  }
  memory.resize(bytes * phases);
  for (int k = 0; k < phases; ++k) job.Write(memory.data() + bytes * k, bytes, k);
  return reply;
}

}  // namespace cinevol::reader

// What stands in front of ITK's NIfTI reader (nifti1_io) inside the cage.
#include "io/formats/nifti/checks.h"

#include <itkImageIOBase.h>
#include <itkMetaDataObject.h>
#include <nifti/nifti1.h>
#include <nifti/nifti2.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"

namespace fs = std::filesystem;

namespace cinevol::formats::nifti {
namespace {

std::string MetaString(const itk::MetaDataDictionary& dict, const std::string& key) {
  std::string value;
  itk::ExposeMetaData<std::string>(dict, key, value);
  return value;
}

template <class T>
T Swapped(T v) {
  auto* b = reinterpret_cast<unsigned char*>(&v);
  std::reverse(b, b + sizeof(T));
  return v;
}

// Headers and NIfTI extensions before the voxels: a few KiB in real files.
constexpr std::int64_t kMaxNiftiOffset = std::int64_t{16} << 20;

// A NIfTI (or Analyze) file opened through zlib (gz or plain: zlib reads
// both) with its header read: where both checks below start.
struct NiftiFile {
  gzFile f = nullptr;
  union {
    nifti_1_header n1;
    nifti_2_header n2;
  } h{};
  bool swap = false;
  int header_size = 0;  // 348: NIfTI-1 or Analyze; 540: NIfTI-2 (read whole)
  NiftiFile() = default;
  NiftiFile(const NiftiFile&) = delete;
  NiftiFile& operator=(const NiftiFile&) = delete;
  ~NiftiFile() {
    if (f) gzclose(f);
  }
};

// ITK's nifti1_io takes a header as NIfTI-1 when it has the NIfTI-1 magic
// (sizeof_hdr then is not checked), and decides its byte order by dim[0]
// when that is set, else by sizeof_hdr; it refuses a header where neither
// order fits. The checks below read the header exactly so: a crafted file
// with a NIfTI-1 magic and a bad sizeof_hdr once slipped past them.
bool NiftiOneMagic(const nifti_1_header& h) {
  return std::memcmp(h.magic, "n+1", 4) == 0 || std::memcmp(h.magic, "ni1", 4) == 0;
}

// Sets `swap` as nifti1_io does; false where it refuses the byte order.
bool NiftiOneByteOrder(const nifti_1_header& h, bool& swap) {
  const auto in_range = [](short d) { return d > 0 && d <= 7; };
  if (h.dim[0] != 0) {
    swap = !in_range(h.dim[0]);
    return !swap || in_range(Swapped(h.dim[0]));
  }
  swap = h.sizeof_hdr != 348;
  return !swap || Swapped(h.sizeof_hdr) == 348;
}

// Opens `path` into `file`; "" or what is wrong ("cannot open", "header is
// truncated", a byte order that the reader refuses).
std::string OpenNifti(const fs::path& path, NiftiFile& file) {
  const int fd = file_checks::OpenRegularFile(path);
  file.f = fd < 0 ? nullptr : gzdopen(fd, "rb");
  if (!file.f) {
    if (fd >= 0) close(fd);
    return "cannot open";
  }
  auto& h = file.h;
  if (gzread(file.f, &h, sizeof(nifti_1_header)) != int(sizeof(nifti_1_header))) return "header is truncated";
  const bool nifti2 = (h.n1.sizeof_hdr == 540 || Swapped(h.n1.sizeof_hdr) == 540) && !NiftiOneMagic(h.n1);
  if (!nifti2) {  // NIfTI-1 or Analyze, the only layouts ITK 5.2 reads
    file.header_size = 348;
    if (!NiftiOneByteOrder(h.n1, file.swap)) return "dim[0] (the number of dimensions) is outside 1..7";
    return "";
  }
  file.header_size = 540;
  file.swap = h.n1.sizeof_hdr != 540;
  const int rest = int(sizeof(nifti_2_header) - sizeof(nifti_1_header));
  if (gzread(file.f, reinterpret_cast<char*>(&h) + sizeof(nifti_1_header), rest) != rest) {
    return "header is truncated";
  }
  return "";
}

// Spacings, offsets and srow entries beyond this (mm) are no real scan's,
// and made ITK's direction SVD run for minutes (a fuzz_volume hang).
constexpr double kMaxNiftiMm = 1e6;

// ITK builds the image direction from these fields with vnl_svd, which
// aborts the process on a NaN or infinity. Returns "" when every field is
// finite and in range, else what is wrong. Analyze 7.5 headers (no NIfTI
// magic) keep other data where the NIfTI orientation is: pixdim only.
template <class Header>
std::string NiftiFieldProblem(const Header& h, bool swap) {
  const auto get = [swap](auto v) { return double(swap ? Swapped(v) : v); };
  const bool nifti = std::memcmp(h.magic, "n+", 2) == 0 || std::memcmp(h.magic, "ni", 2) == 0;
  std::vector<double> values, spatial;
  for (int i = 0; i < 8; ++i) (i >= 1 && i <= 3 ? spatial : values).push_back(get(h.pixdim[i]));
  if (nifti) {
    for (auto v : {h.quatern_b, h.quatern_c, h.quatern_d, h.scl_slope, h.scl_inter, h.toffset})
      values.push_back(get(v));
    for (auto v : {h.qoffset_x, h.qoffset_y, h.qoffset_z}) spatial.push_back(get(v));
    for (int i = 0; i < 4; ++i) {
      for (auto v : {h.srow_x[i], h.srow_y[i], h.srow_z[i]}) spatial.push_back(get(v));
    }
  }
  values.insert(values.end(), spatial.begin(), spatial.end());
  if (!std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); })) {
    return "the header's spacing, orientation or scaling holds a value that is not a finite number";
  }
  if (!std::all_of(spatial.begin(), spatial.end(), [](double v) { return std::fabs(v) <= kMaxNiftiMm; })) {
    return fmt::format("the header's spacing, orientation or scaling holds a value beyond {:.0f} mm", kMaxNiftiMm);
  }
  return "";
}

// The header ITK's NIfTI reader will parse (NIfTI-1/-2 or Analyze, gz or
// plain), read as NiftiPayloadProblem reads it; "" when it is fine or is not
// such a header (ITK then refuses it itself).
std::string NiftiHeaderProblem(const fs::path& path) {
  NiftiFile file;
  if (!OpenNifti(path, file).empty()) return "";
  if (file.header_size == 348) return NiftiFieldProblem(file.h.n1, file.swap);
  if (file.header_size == 540) return NiftiFieldProblem(file.h.n2, file.swap);
  return "";
}

// `path`'s name in lower case without a ".gz": "x.hdr" for "X.HDR.gz".
std::string PlainLowerName(const fs::path& path) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (name.size() > 3 && name.compare(name.size() - 3, 3, ".gz") == 0) name.resize(name.size() - 3);
  return name;
}

// The files beside `path` with its name and one of `endings` in its place
// (.hdr for an .img, say), those that are regular files.
using Endings = std::array<const char*, 4>;

std::vector<fs::path> Siblings(const fs::path& path, const Endings& endings) {
  const std::string base = path.filename().string().substr(0, PlainLowerName(path).size() - 4);
  std::vector<fs::path> found;
  for (const char* ending : endings) {
    const fs::path sibling = path.parent_path() / (base + ending);
    if (sibling != path && file_checks::IsRegularFile(sibling)) found.push_back(sibling);
  }
  return found;
}

constexpr Endings kHeaderEndings{".hdr", ".HDR", ".hdr.gz", ".HDR.gz"};
constexpr Endings kImageEndings{".img", ".IMG", ".img.gz", ".IMG.gz"};

// The file that holds `path`'s header and the one that holds its voxels: a
// .nii holds both; of a .hdr/.img pair each is found beside the other.
struct HeaderAndVoxels {
  fs::path header, voxels;
};
HeaderAndVoxels PartsOf(const fs::path& path) {
  const std::string name = PlainLowerName(path);
  const std::string ext = name.size() > 4 ? name.substr(name.size() - 4) : "";
  const auto first = [](const std::vector<fs::path>& files) { return files.empty() ? fs::path() : files.front(); };
  if (ext == ".hdr") return {path, first(Siblings(path, kImageEndings))};
  if (ext == ".img") return {first(Siblings(path, kHeaderEndings)), path};
  return {path, path};
}

}  // namespace

bool StatesOrientation(const fs::path& path) {
  const HeaderAndVoxels parts = PartsOf(path);
  NiftiFile file;
  if (parts.header.empty() || !OpenNifti(parts.header, file).empty()) return false;
  const auto& h = file.h;
  const bool swap = file.swap;
  if (file.header_size == 348) {
    if (!NiftiOneMagic(h.n1)) return false;  // Analyze 7.5: no orientation fields
    return (swap ? Swapped(h.n1.qform_code) : h.n1.qform_code) > 0 || (swap ? Swapped(h.n1.sform_code) : h.n1.sform_code) > 0;
  }
  return (swap ? Swapped(h.n2.qform_code) : h.n2.qform_code) > 0 || (swap ? Swapped(h.n2.sform_code) : h.n2.sform_code) > 0;
}

// ITK's NIfTI reader pads a short payload with zeros instead of failing, so
// the payload is counted here first (gz or plain: zlib reads both), in the
// file that holds it (the .img of a pair, from its vox_offset). Returns ""
// when the file holds every voxel, else what is missing.
std::string PayloadProblem(const fs::path& path) {
  const HeaderAndVoxels parts = PartsOf(path);
  if (parts.header.empty()) return "the .hdr beside this .img is missing";
  if (parts.voxels.empty()) return "the .img beside this .hdr is missing";
  NiftiFile file;
  if (std::string problem = OpenNifti(parts.header, file); !problem.empty()) return problem;
  const auto& h = file.h;
  const bool swap = file.swap;
  const int header_size = file.header_size;
  NiftiFile pair_voxels;  // the .img's own, opened without reading a header
  if (parts.voxels != parts.header) {
    const int fd = file_checks::OpenRegularFile(parts.voxels);
    pair_voxels.f = fd < 0 ? nullptr : gzdopen(fd, "rb");
    if (!pair_voxels.f) {
      if (fd >= 0) close(fd);
      return "cannot open the .img of the pair";
    }
  }
  gzFile f = pair_voxels.f ? pair_voxels.f : file.f;
  std::int64_t voxels = 1, bitpix = 0;
  double offset_field = 0;  // vox_offset: a float in NIfTI-1, checked before it becomes an integer
  if (header_size == 348) {
    const int ndim = std::clamp<int>(swap ? Swapped(h.n1.dim[0]) : h.n1.dim[0], 1, 7);
    for (int i = 1; i <= ndim; ++i) voxels *= swap ? Swapped(h.n1.dim[i]) : h.n1.dim[i];
    bitpix = swap ? Swapped(h.n1.bitpix) : h.n1.bitpix;
    offset_field = swap ? Swapped(h.n1.vox_offset) : h.n1.vox_offset;
  } else {
    const int ndim = int(std::clamp<std::int64_t>(swap ? Swapped(h.n2.dim[0]) : h.n2.dim[0], 1, 7));
    for (int i = 1; i <= ndim; ++i) voxels *= swap ? Swapped(h.n2.dim[i]) : h.n2.dim[i];
    bitpix = swap ? Swapped(h.n2.bitpix) : h.n2.bitpix;
    offset_field = double(swap ? Swapped(h.n2.vox_offset) : h.n2.vox_offset);
  }
  // The readers inflate up to vox_offset too; extensions past it are absurd.
  if (!(offset_field >= 0 && offset_field <= double(kMaxNiftiOffset))) {
    return fmt::format("vox_offset {} is outside [0, {}]", offset_field, kMaxNiftiOffset);
  }
  const auto offset = std::int64_t(offset_field);
  const std::int64_t expected = offset + voxels * bitpix / 8;
  std::int64_t total = pair_voxels.f ? 0 : header_size == 348 ? sizeof(nifti_1_header) : sizeof(nifti_2_header);
  std::vector<char> buffer(1 << 20);
  // Inflates only what the header promises (whose voxel count was checked
  // already): a small .nii.gz can expand without bound.
  for (int n = 1; total < expected && n > 0; total += n) {
    n = gzread(f, buffer.data(), unsigned(std::min<std::int64_t>(std::int64_t(buffer.size()), expected - total)));
    if (n < 0) break;
  }
  int err = Z_OK;
  const char* message = gzerror(f, &err);
  if (err != Z_OK && err != Z_STREAM_END) return fmt::format("compressed data are damaged ({})", message);
  if (total < expected) {
    return fmt::format("truncated: the header promises {} bytes of voxel data, the file holds {}",
                       expected - offset, std::max<std::int64_t>(0, total - offset));
  }
  return "";
}

// ITK's NIfTI reader takes a file by its name (.nii, .hdr, .img, any case,
// optionally .gz) and parses the header while ReadImageInformation runs, so
// the header (an .img's is in the .hdr beside it) is checked before that.
void CheckHeaders(const fs::path& path, const std::string& shown) {
  const std::string name = PlainLowerName(path);
  const std::string ext = name.size() > 4 ? name.substr(name.size() - 4) : "";
  std::vector<fs::path> headers;
  if (ext == ".nii" || ext == ".hdr") headers.push_back(path);
  if (ext == ".img") headers = Siblings(path, kHeaderEndings);
  for (const fs::path& header : headers) {
    const std::string problem = NiftiHeaderProblem(header);
    if (!problem.empty()) throw InputError(fmt::format("{}: {}", shown, problem));
  }
}

// ITK reports NIfTI data with a scl_slope as float; the header's datatype
// says what is really there.
std::string StoredType(const itk::ImageIOBase& io) {
  const auto& dict = io.GetMetaDataDictionary();
  const std::string datatype = MetaString(dict, "datatype");
  if (datatype.empty()) return "";
  static const std::map<std::string, std::string> kNifti = {
      {"2", "uint8"},   {"4", "int16"},   {"8", "int32"},    {"16", "float32"}, {"64", "float64"},
      {"256", "int8"}, {"512", "uint16"}, {"768", "uint32"}, {"1024", "int64"}, {"1280", "uint64"}};
  const auto it = kNifti.find(datatype);
  std::string type = it != kNifti.end() ? it->second : "NIfTI datatype " + datatype;
  const std::string slope = MetaString(dict, "scl_slope"), inter = MetaString(dict, "scl_inter");
  if ((!slope.empty() && slope != "0" && slope != "1") || (!inter.empty() && inter != "0")) {
    type += fmt::format(" (scl_slope {}, scl_inter {})", slope, inter.empty() ? "0" : inter);
  }
  return type;
}

}  // namespace cinevol::formats::nifti

// Volume files through ITK: NIfTI, NRRD/NHDR, MetaImage and VTK legacy.
#include <gdcmGlobal.h>
#include <gdcmTrace.h>
#include <itkGDCMImageIO.h>
#include <itkImageFileReader.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIOFactory.h>
#include <itkVTKImageIOFactory.h>
#include <nifti/nifti1.h>
#include <nifti/nifti2.h>
#include <zlib.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"
#include "io/file_checks.h"
#include "io/formats/format.h"
#include "io/formats/header_text.h"
#include "io/formats/nrrd/references.h"
#include "io/readers/formats.h"
#include "io/readers/itk_image.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace itk_image {

// The formats are registered explicitly rather than through ITK's
// CMake-generated factory list, so the set is visible here. GDCM is not among
// them: DICOM is read from a folder (dicom_series.cpp makes its GDCMImageIO
// after its own checks), and the factory would have GDCM parse any file the
// other formats decline (GDCM asserts, aborting, on a malformed meta group).
void InitToolkits() {
  static std::once_flag once;
  std::call_once(once, [] {
    itk::NiftiImageIOFactory::RegisterOneFactory();
    itk::NrrdImageIOFactory::RegisterOneFactory();
    itk::MetaImageIOFactory::RegisterOneFactory();
    itk::VTKImageIOFactory::RegisterOneFactory();
    itk::Object::GlobalWarningDisplayOff();
    gdcm::Trace::WarningOff();
    gdcm::Trace::DebugOff();
  });
}

void WarmUp() {
  InitToolkits();
  gdcm::Global::GetInstance().GetDicts();  // the DICOM dictionary
  itk::GDCMImageIO::New();
  for (const char* name : {"x.nii", "x.nrrd", "x.mha", "x.vtk"}) {
    itk::ImageIOFactory::CreateImageIO(name, itk::IOFileModeEnum::ReadMode);
  }
}

std::string ComponentName(itk::IOComponentEnum type) {
  using C = itk::IOComponentEnum;
  switch (type) {
    case C::UCHAR: return "uint8";
    case C::CHAR: return "int8";
    case C::USHORT: return "uint16";
    case C::SHORT: return "int16";
    case C::UINT: return "uint32";
    case C::INT: return "int32";
    case C::ULONG: case C::ULONGLONG: return "uint64";
    case C::LONG: case C::LONGLONG: return "int64";
    case C::FLOAT: return "float32";
    case C::DOUBLE: return "float64";
    default: return itk::ImageIOBase::GetComponentTypeAsString(type);
  }
}

std::string ItkMessage(const itk::ExceptionObject& e, const std::vector<fs::path>& paths,
                       const std::string& shown) {
  std::string d = e.GetDescription();
  const auto colon = d.find("): ");
  if (d.rfind("ITK ERROR", 0) == 0 && colon != std::string::npos) d = d.substr(colon + 3);
  std::vector<std::string> forms;
  for (const fs::path& p : paths) {
    std::error_code ec;
    for (const fs::path& form : {p, fs::absolute(p, ec), fs::weakly_canonical(p, ec)}) {
      if (!form.empty() && form.string() != shown) forms.push_back(form.string());
    }
  }
  // Longest first, so a path is replaced whole rather than its relative tail.
  std::sort(forms.begin(), forms.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  for (const std::string& form : forms) {
    for (auto at = d.find(form); at != std::string::npos; at = d.find(form, at + shown.size())) {
      d.replace(at, form.size(), shown);
    }
  }
  static const std::regex kSourceLocation(R"([\w./+-]+\.(cxx|cpp|hxx|txx|c|h):\d+:?\s*)");
  static const std::regex kItkPrefix(R"((ITK ERROR|itk::ERROR): \w+\(0x[0-9a-fA-F]+\): )");
  d = std::regex_replace(std::regex_replace(d, kSourceLocation, ""), kItkPrefix, "");
  // teem stacks "[nrrd] function: ..." lines, the cause last: keep that.
  if (const auto nrrd = d.rfind("[nrrd] "); nrrd != std::string::npos) {
    d = d.substr(nrrd + 7);
    d = d.substr(d.find(": ") == std::string::npos ? 0 : d.find(": ") + 2);
  }
  while (!d.empty() && (d.back() == '\n' || d.back() == ' ')) d.pop_back();
  return d;
}

std::string VoxelTypeOf(itk::IOComponentEnum type) {
  const std::string name = ComponentName(type);
  return VoxelTypeNamed(name) ? name : "";
}

void SetGeometry(reader::Header& header, const std::array<int, 3>& dims, std::array<double, 3> spacing,
                 const std::array<double, 3>& origin, std::array<double, 9> direction) {
  // As ITK's ImageFileReader: a negative spacing flips its axis instead, and
  // a direction that is no rotation (determinant 0) becomes the identity.
  for (int c = 0; c < 3; ++c) {
    if (spacing[c] < 0) {
      spacing[c] = -spacing[c];
      for (int r = 0; r < 3; ++r) direction[3 * r + c] = -direction[3 * r + c];
    }
  }
  const auto& d = direction;
  const double det = d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) +
                     d[2] * (d[3] * d[7] - d[4] * d[6]);
  if (!(std::fabs(det) > 1e-6)) direction = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  header.clear_dims();
  header.clear_spacing_mm();
  header.clear_origin_mm();
  header.clear_direction();
  for (int a = 0; a < 3; ++a) {
    header.add_dims(std::uint32_t(dims[a]));
    header.add_spacing_mm(spacing[a]);
    header.add_origin_mm(origin[a]);
  }
  for (double v : direction) header.add_direction(v);
}

}  // namespace itk_image

namespace {


// "unknown" ITK enum values print as numbers; name the ones cinevol accepts.
bool IsSupportedComponent(itk::IOComponentEnum c) {
  using C = itk::IOComponentEnum;
  switch (c) {
    case C::UCHAR: case C::CHAR: case C::USHORT: case C::SHORT: case C::UINT: case C::INT:
    case C::ULONG: case C::LONG: case C::ULONGLONG: case C::LONGLONG: case C::FLOAT:
    case C::DOUBLE:
      return true;
    default:
      return false;
  }
}

// The lines teem skips before the voxels: a header's own `line skip` field.
std::int64_t LineSkip(const std::string& line, const std::string& shown) {
  const std::string value = line.substr(std::min(line.size(), line.find_first_not_of(" \t", line.find(':') + 1)));
  std::int64_t n = 0;
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
  if (ec != std::errc() || n < 0) throw InputError(fmt::format("{}: 'line skip' is not a count", shown));
  return n;
}

// Replaces the scratch file's text with `text`; returns its path.
fs::path WriteScratch(const std::string& text, const reader::ReadOptions& options) {
  if (options.scratch_fd < 0 || ftruncate(options.scratch_fd, 0) != 0 ||
      pwrite(options.scratch_fd, text.data(), text.size(), 0) != ssize_t(text.size())) {
    throw InputError(fmt::format("{}: cannot rewrite the header ({} bytes)", options.shown, text.size()));
  }
  return options.scratch_path;
}

// A NRRD header whose other files are where the cage placed them (`named`,
// in the header's order) and, with `drop_space`, without its `space` line:
// some published detached headers give both `space` and per-axis `spacings`,
// which teem refuses, and the intent is plain (the spacings are the voxel
// size). Attached voxels are read from `header` itself past its lines.
fs::path RewriteNrrdHeader(const fs::path& header, const std::vector<fs::path>& named, bool drop_space,
                           const reader::ReadOptions& options) {
  const std::string& shown = options.shown;
  const formats::nrrd::Header h = formats::nrrd::ParseHeader(header, shown);
  if (!h.references.problem.empty()) throw InputError(fmt::format("{}: {}", shown, h.references.problem));
  if (!h.attached && h.references.files.size() != named.size()) {
    throw InputError(fmt::format("{}: the header changed while it was read", shown));
  }
  std::string out;
  std::int64_t line_skip = 0;
  for (const std::string& line : h.lines) {
    const std::string key = formats::nrrd::FieldName(line);
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
  return WriteScratch(out, options);
}

// A MetaImage header whose ElementDataFile names where the cage placed the
// files (`named`, in the header's order): a single file, or a LIST.
fs::path RewriteMetaImageHeader(const fs::path& header, const std::vector<fs::path>& named,
                                const reader::ReadOptions& options) {
  const std::string head = file_checks::ReadHead(header, formats::kMaxHeaderBytes, options.shown);
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
    return WriteScratch(out, options);
  }
  throw InputError(fmt::format("{}: the header changed while it was read", options.shown));
}

bool IsSpaceWithSpacingsError(const itk::ExceptionObject& e) {
  return std::string(e.GetDescription()).find("ScalarWithSpace") != std::string::npos;
}

std::string TrimBlanks(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r");
  return first == std::string::npos ? "" : s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

// MetaIO copies each key it reads (up to 500 characters, up to '=', ':' or a
// line end) into a 255-byte field name: a longer run overflows it (an abort
// under _FORTIFY_SOURCE, found by fuzz_volume). A run can start anywhere (the
// rest of a value MetaIO did not take is read as the next key), so no run of
// the header, up to its ElementDataFile line, may reach 255 characters.
void CheckMetaHeaderText(const fs::path& path, const std::string& shown) {
  const std::string head = file_checks::ReadHead(path, formats::kMaxHeaderBytes, shown);
  constexpr std::size_t kMaxRun = 254;
  const std::size_t end = std::min(head.size(), head.find('\n', std::min(head.size(), head.find("ElementDataFile"))));
  // MetaIO reads NDims values for DimSize and the like (NDims squared for a
  // matrix) into arrays of 10 (100): a negative or large NDims made it loop
  // for hours (found by fuzz_volume) or write past them.
  for (std::size_t pos = 0; pos < end;) {
    const std::size_t line_end = std::min(head.find_first_of("\r\n", pos), end);
    const std::size_t sep = head.find_first_of("=:", pos);
    if (TrimBlanks(head.substr(pos, std::min(sep, line_end) - pos)) == "NDims") {
      const std::size_t from = sep == std::string::npos ? head.size() : sep + 1;
      const std::size_t to = std::min(head.find_first_of("\r\n", std::min(from, head.size())), head.size());
      const std::string value = from < to ? TrimBlanks(head.substr(from, to - from)) : "";
      char* stop = nullptr;
      const double n = std::strtod(value.c_str(), &stop);
      if (stop == value.c_str() || !(n >= 1 && n <= 10) || n != std::floor(n)) {
        throw InputError(fmt::format("{}: NDims '{}' is not a dimension count (1 to 10)", shown, value.substr(0, 32)));
      }
    }
    pos = line_end + 1;
  }
  std::size_t run = 0;
  for (std::size_t i = 0; i < end; ++i) {
    const char c = head[i];
    run = (c == '=' || c == ':' || c == '\r' || c == '\n') ? 0 : run + 1;
    if (run > kMaxRun) {
      throw InputError(fmt::format("{}: a header line holds more than {} characters between separators", shown,
                                   kMaxRun));
    }
  }
}

// teem copies a per-axis field's values ("sizes", "spacings", "space
// directions", ...) through fixed buffers: a line of about 1,000 characters
// (extra values, trailing blanks) aborts it under _FORTIFY_SOURCE. Real
// lines are a few dozen characters; free text ("content", comments and
// key/value pairs) is not limited.
void CheckNrrdHeaderText(const fs::path& path, const std::string& shown) {
  constexpr std::size_t kMaxFieldLine = 512;
  const formats::nrrd::Header h = formats::nrrd::ParseHeader(path, shown);
  for (std::size_t i = 1; i < h.lines.size(); ++i) {
    const std::string& line = h.lines[i];
    const std::string key = formats::nrrd::FieldName(line);
    if (key.empty() || key == "content" || line.find(":=") != std::string::npos) continue;
    if (line.size() > kMaxFieldLine) {
      throw InputError(fmt::format("{}: the header's '{}' line has {} characters; cinevol reads NRRD field lines of "
                                   "up to {}",
                                   shown, line.substr(0, line.find(':')), line.size(), kMaxFieldLine));
    }
  }
}

itk::ImageIOBase::Pointer ReadHeader(const fs::path& path, const std::string& shown, bool prechecks) {
  itk_image::InitToolkits();
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  if (!io) {
    throw InputError(fmt::format(
        "{}: not a volume format cinevol reads (NIfTI, NRRD/NHDR, MetaImage, VTK; "
        "DICOM is read from a folder)",
        shown));
  }
  io->SetFileName(path.string());
  if (prechecks && dynamic_cast<itk::MetaImageIO*>(io.GetPointer())) CheckMetaHeaderText(path, shown);
  if (prechecks && std::string(io->GetNameOfClass()) == "NrrdImageIO") CheckNrrdHeaderText(path, shown);
  io->ReadImageInformation();
  return io;
}

void CheckHeader(const std::string& shown, itk::ImageIOBase& io, std::uint64_t max_voxels) {
  const unsigned dims = io.GetNumberOfDimensions();
  if (dims < 2 || dims > 3) {
    throw InputError(fmt::format("{}: a {}-D image; cinevol reads 2-D and 3-D scalar volumes",
                                 shown, dims));
  }
  if (io.GetNumberOfComponents() != 1) {
    throw InputError(fmt::format("{}: {} components per voxel ({}); cinevol needs one scalar",
                                 shown, io.GetNumberOfComponents(),
                                 io.GetPixelTypeAsString(io.GetPixelType())));
  }
  if (!IsSupportedComponent(io.GetComponentType())) {
    throw InputError(fmt::format("{}: unsupported voxel type '{}'", shown,
                                 io.GetComponentTypeAsString(io.GetComponentType())));
  }
  Vec3i size{1, 1, 1};
  Vec3f spacing{1, 1, 1};
  for (unsigned a = 0; a < dims; ++a) {
    // Sizes past int range are absurd; clamp so the check below names them.
    size[a] = int(std::min<itk::SizeValueType>(io.GetDimensions(a), 1u << 30));
    spacing[a] = float(io.GetSpacing(a));
  }
  CheckVolumeGeometry(size, spacing, shown);
  const std::uint64_t voxels = std::uint64_t(size.x) * std::uint64_t(size.y) * std::uint64_t(size.z);
  if (voxels > max_voxels) {
    throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds this server's limit of {} voxels", shown,
                                 size.x, size.y, size.z, voxels, max_voxels));
  }
}

std::string MetaString(const itk::MetaDataDictionary& dict, const std::string& key) {
  std::string value;
  itk::ExposeMetaData<std::string>(dict, key, value);
  return value;
}

// The voxel type as stored in the file. ITK reports NIfTI data with a
// scl_slope as float; the header's datatype says what is really there.
std::string OriginalType(const itk::ImageIOBase& io) {
  const auto& dict = io.GetMetaDataDictionary();
  const std::string datatype = MetaString(dict, "datatype");
  if (datatype.empty()) return itk_image::ComponentName(io.GetComponentType());
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

// ITK's NIfTI reader pads a short payload with zeros instead of failing, so
// the payload is counted here first (gz or plain: zlib reads both). Returns
// "" when the file holds every voxel, else what is missing.
std::string NiftiPayloadProblem(const fs::path& path) {
  NiftiFile file;
  if (std::string problem = OpenNifti(path, file); !problem.empty()) return problem;
  const auto& h = file.h;
  const bool swap = file.swap;
  const int header_size = file.header_size;
  gzFile f = file.f;
  std::int64_t voxels = 1, bitpix = 0, offset = 0;
  if (header_size == 348) {
    const int ndim = std::clamp<int>(swap ? Swapped(h.n1.dim[0]) : h.n1.dim[0], 1, 7);
    for (int i = 1; i <= ndim; ++i) voxels *= swap ? Swapped(h.n1.dim[i]) : h.n1.dim[i];
    bitpix = swap ? Swapped(h.n1.bitpix) : h.n1.bitpix;
    offset = std::int64_t(swap ? Swapped(h.n1.vox_offset) : h.n1.vox_offset);
  } else {
    const int ndim = int(std::clamp<std::int64_t>(swap ? Swapped(h.n2.dim[0]) : h.n2.dim[0], 1, 7));
    for (int i = 1; i <= ndim; ++i) voxels *= swap ? Swapped(h.n2.dim[i]) : h.n2.dim[i];
    bitpix = swap ? Swapped(h.n2.bitpix) : h.n2.bitpix;
    offset = swap ? Swapped(h.n2.vox_offset) : h.n2.vox_offset;
  }
  // The readers inflate up to vox_offset too; extensions past it are absurd.
  if (offset < 0 || offset > kMaxNiftiOffset) {
    return fmt::format("vox_offset {} is outside [0, {}]", offset, kMaxNiftiOffset);
  }
  const std::int64_t expected = offset + voxels * bitpix / 8;
  std::int64_t total = header_size == 348 ? sizeof(nifti_1_header) : sizeof(nifti_2_header);
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
    for (auto v : {h.quatern_b, h.quatern_c, h.quatern_d, h.scl_slope, h.scl_inter, h.toffset}) values.push_back(get(v));
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

// ITK's NIfTI reader takes a file by its name (.nii, .hdr, .img, any case,
// optionally .gz) and parses the header while ReadImageInformation runs, so
// the header (an .img's is in the .hdr beside it) is checked before that.
void CheckNiftiHeaders(const fs::path& path, const std::string& shown) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (name.size() > 3 && name.compare(name.size() - 3, 3, ".gz") == 0) name.resize(name.size() - 3);
  const std::string ext = name.size() > 4 ? name.substr(name.size() - 4) : "";
  std::vector<fs::path> headers;
  if (ext == ".nii" || ext == ".hdr") headers.push_back(path);
  if (ext == ".img") {
    const std::string base = path.filename().string().substr(0, name.size() - 4);
    for (const char* hdr : {".hdr", ".HDR", ".hdr.gz", ".HDR.gz"}) headers.push_back(path.parent_path() / (base + hdr));
  }
  for (const fs::path& header : headers) {
    if (header != path && !file_checks::IsRegularFile(header)) continue;
    const std::string problem = NiftiHeaderProblem(header);
    if (!problem.empty()) throw InputError(fmt::format("{}: {}", shown, problem));
  }
}


// The byte offset just past the first `lines` lines of `text`, with line ends
// counted as formats::Lines counts them ("\n", "\r" or "\r\n"); -1 when
// the text has fewer.
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

// teem (ITK's NRRD reader) leaks its state whenever the voxels cannot be
// read (a short or damaged payload, a bad number in ASCII data): a few KiB
// per load, tens of KiB for gzip. So the payload of a NRRD in one file
// (attached, or one detached data file) is checked here first, as teem will
// read it. Returns "" when it holds every voxel, else what is wrong.
std::string NrrdPayloadProblem(itk::ImageIOBase& io, const fs::path& path, const std::string& shown) {
  const formats::nrrd::Header h = formats::nrrd::ParseHeader(path, shown);
  if (h.listed || !h.references.problem.empty() || (!h.attached && h.references.files.size() != 1)) return "";
  std::string encoding = "raw";
  std::int64_t line_skip = 0, byte_skip = 0;
  for (const std::string& line : h.lines) {
    const std::string key = formats::nrrd::FieldName(line);
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
    start = OffsetAfterLines(file_checks::ReadHead(data, formats::kMaxHeaderBytes + 1, shown), h.line_count);
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
  const std::string shown_data = h.attached ? "the file" : "'" + data.filename().string() + "'";
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

// The MetaImage header as MetaIO reads it: "Key = value" lines, the last
// ElementDataFile; LOCAL data begin right after that line.
struct MetaHeader {
  std::int64_t data_start = -1;        // -1: no ElementDataFile line found
  std::int64_t header_size = 0;        // HeaderSize: bytes skipped before the data
  double compressed_size = -1;         // CompressedDataSize; -1 when absent
};

MetaHeader ReadMetaHeader(const fs::path& path, const std::string& shown) {
  const std::string head = file_checks::ReadHead(path, formats::kMaxHeaderBytes, shown);
  MetaHeader h;
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

// MetaIO's own reading of a header's fields (CompressedDataSize has no
// accessor: a pointer to the protected member, named through a derived class).
struct MetaFields : MetaImage {
  static std::streamoff CompressedDataSize(const MetaImage& m) { return m.*(&MetaFields::m_CompressedDataSize); }
};

// Where MetaIO finds LOCAL data: just past the header as MetaIO itself reads
// it (the same parse ITK's reader makes before reading the voxels); -1 when
// it cannot tell.
std::int64_t MetaLocalDataStart(const fs::path& path) {
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
std::string MetaCompressedProblem(const fs::path& data, std::int64_t start, std::int64_t length,
                                  std::int64_t expected, const std::string& shown_data) {
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

// ITK's MetaImage and VTK readers warn about a short payload on stderr and
// carry on. For uncompressed data the file that holds the voxels must be at
// least as long as they are (a LOCAL MetaImage's header not counted), and
// compressed MetaImage data no longer than the file: MetaIO allocates what
// CompressedDataSize says before reading.
std::string RawPayloadProblem(itk::ImageIOBase& io, const fs::path& path, const std::string& shown) {
  fs::path data = path;
  // Bytes of `data` before the voxels: a LOCAL MetaImage's header, HeaderSize.
  std::int64_t skip = 0;
  if (auto* meta = dynamic_cast<itk::MetaImageIO*>(&io)) {
    const std::string file = meta->GetMetaImagePointer()->ElementDataFileName();
    if (file == "LIST" || file.find('%') != std::string::npos || file.find(' ') != std::string::npos) return "";
    const bool local = file == "LOCAL" || file == "Local" || file == "local";
    if (!local) data = fs::path(file).is_absolute() ? fs::path(file) : path.parent_path() / file;
    const MetaHeader h = ReadMetaHeader(path, shown);
    skip = (local ? std::max<std::int64_t>(0, h.data_start) : 0) + std::max<std::int64_t>(0, h.header_size);
    const MetaImage& image = *meta->GetMetaImagePointer();
    if (image.CompressedData()) {
      // MetaIO reads compressed data from just past the header (LOCAL) or the
      // data file's start; it skips no HeaderSize the same way on every path.
      if (image.HeaderSize() != 0) return "'HeaderSize' is for uncompressed data only";
      const std::int64_t start = local ? MetaLocalDataStart(path) : 0;
      if (start < 0) return "cannot find where the compressed data begin";
      std::error_code ec;
      const std::int64_t size = file_checks::IsRegularFile(data) ? std::int64_t(fs::file_size(data, ec)) : 0;
      if (ec || !file_checks::IsRegularFile(data)) return "cannot read the file that ElementDataFile names";
      const std::string shown_data = local ? "the file after its header" : "'" + data.filename().string() + "'";
      // MetaIO allocates CompressedDataSize bytes before it reads them; 0
      // (or none given) means the rest of the file.
      const std::int64_t declared = MetaFields::CompressedDataSize(image);
      if (declared < 0) return fmt::format("CompressedDataSize {} is negative", declared);
      if (!(h.compressed_size <= double(size - start)) || declared > size - start) {
        return fmt::format("CompressedDataSize {} is more than {} holds ({} bytes)",
                           std::max(h.compressed_size, double(declared)), shown_data,
                           std::max<std::int64_t>(0, size - start));
      }
      return MetaCompressedProblem(data, start, declared > 0 ? declared : size - start,
                                   std::int64_t(io.GetImageSizeInBytes()), shown_data);
    }
    if (h.header_size < 0) skip = 0;  // HeaderSize -1: the voxels are the file's last bytes
  } else if (std::string(io.GetNameOfClass()) != "VTKImageIO" || io.GetFileType() != itk::IOFileEnum::Binary) {
    return "";
  }
  std::error_code ec;
  const auto size = file_checks::IsRegularFile(data) ? fs::file_size(data, ec) : 0;
  if (ec || !file_checks::IsRegularFile(data)) return "cannot read the file that ElementDataFile names";
  if (std::int64_t(size) - skip < std::int64_t(io.GetImageSizeInBytes())) {
    return fmt::format("truncated: {} voxel bytes expected, {} holds {}", io.GetImageSizeInBytes(),
                       data == path ? (skip > 0 ? "the file after its header" : "the file")
                                    : "'" + data.filename().string() + "'",
                       std::max<std::int64_t>(0, std::int64_t(size) - skip));
  }
  return "";
}

std::string MetaImageModality(itk::ImageIOBase& io) {
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
void CheckMetaImageDataFile(itk::ImageIOBase& io, const fs::path& path, const std::vector<fs::path>& placed,
                            const std::string& shown) {
  auto* meta = dynamic_cast<itk::MetaImageIO*>(&io);
  if (!meta) return;
  const std::string name = meta->GetMetaImagePointer()->ElementDataFileName();
  if (name == "LOCAL" || name == "Local" || name == "local") return;
  const bool listed = name.rfind("LIST", 0) == 0 || name.find('%') != std::string::npos;
  const fs::path file = (!name.empty() && name[0] == '/' ? fs::path(name) : path.parent_path() / name).lexically_normal();
  const bool seen = std::any_of(placed.begin(), placed.end(), [&](const fs::path& p) {
    return fs::absolute(p).lexically_normal() == fs::absolute(file).lexically_normal();
  });
  if ((listed && placed.empty()) || (!listed && !seen)) {
    throw InputError(fmt::format("{}: the header's 'ElementDataFile' names a file the header check did not see",
                                 shown));
  }
}

// A volume file opened through ITK: the header read and checked, the voxels
// not yet.
class ItkVolumeRead final : public reader::VolumeRead {
 public:
  ItkVolumeRead(itk::ImageIOBase::Pointer io, const fs::path& path, const reader::ReadOptions& options)
      : io_(std::move(io)), path_(path), shown_(options.shown), prechecks_(options.prechecks) {
    const unsigned n = io_->GetNumberOfDimensions();
    std::array<int, 3> dims{1, 1, 1};
    std::array<double, 3> spacing{1, 1, 1}, origin{0, 0, 0};
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (unsigned c = 0; c < n; ++c) {
      dims[c] = int(io_->GetDimensions(c));
      spacing[c] = io_->GetSpacing(c);
      origin[c] = io_->GetOrigin(c);
      const std::vector<double> axis = io_->GetDirection(c);
      for (unsigned r = 0; r < n && r < axis.size(); ++r) direction[3 * r + c] = axis[r];
    }
    itk_image::SetGeometry(header_, dims, spacing, origin, direction);
    header_.set_voxel_type(itk_image::VoxelTypeOf(io_->GetComponentType()));
    header_.set_original_type(OriginalType(*io_));
    header_.set_modality(MetaImageModality(*io_));
    if (header_.modality() == "CT") header_.set_value_unit("HU");
  }

  void Read(void* memory, std::size_t bytes) override {
    // The payload is checked now, once the parent has counted the memory the
    // header asks for: a small compressed file may inflate to gigabytes.
    if (prechecks_) {
      const std::string kind = io_->GetNameOfClass();
      const std::string problem = kind == "NiftiImageIO"  ? NiftiPayloadProblem(path_)
                                  : kind == "NrrdImageIO" ? NrrdPayloadProblem(*io_, path_, shown_)
                                                          : RawPayloadProblem(*io_, path_, shown_);
      if (!problem.empty()) throw InputError(fmt::format("{}: {}", shown_, problem));
    }
    if (bytes != io_->GetImageSizeInBytes()) {
      throw InputError(fmt::format("{}: {} bytes of memory for {} bytes of voxels", shown_, bytes,
                                   io_->GetImageSizeInBytes()));
    }
    const unsigned n = io_->GetNumberOfDimensions();
    itk::ImageIORegion region(n);
    for (unsigned a = 0; a < n; ++a) {
      region.SetIndex(a, 0);
      region.SetSize(a, io_->GetDimensions(a));
    }
    io_->SetIORegion(region);
    try {
      io_->Read(memory);
    } catch (const itk::ExceptionObject& e) {
      throw InputError(fmt::format("{}: {}", shown_, itk_image::ItkMessage(e, {io_->GetFileName()}, shown_)));
    }
  }

 private:
  itk::ImageIOBase::Pointer io_;
  fs::path path_;
  std::string shown_;
  bool prechecks_;
};

// Opens `path` (the file, or the cage's rewrite of its header) with ITK.
std::unique_ptr<reader::VolumeRead> OpenWithItk(const fs::path& path, const std::vector<fs::path>& placed,
                                                const reader::ReadOptions& options) {
  const std::string& shown = options.shown;
  if (options.prechecks) CheckNiftiHeaders(path, shown);
  auto io = ReadHeader(path, shown, options.prechecks);
  CheckHeader(shown, *io, options.max_voxels);
  CheckMetaImageDataFile(*io, path, placed, shown);
  return std::make_unique<ItkVolumeRead>(io, path, options);
}

bool IsGzippedNrrd(const fs::path& path) {
  std::string name = path.filename().string();
  for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
  return name.ends_with(".nrrd.gz");
}

// A whole NRRD file gzipped (.nrrd.gz): teem inflates gzip only as a NRRD's
// encoding of its voxels. So the header, read through zlib, is rewritten as a
// detached header that names the file itself as its data, gzip-encoded, with
// a byte skip past the header: teem inflates the file and skips what the
// header took.
fs::path RewriteGzippedNrrd(const fs::path& path, const reader::ReadOptions& options) {
  const std::string& shown = options.shown;
  const int fd = file_checks::OpenRegularFile(path);
  gzFile z = fd < 0 ? nullptr : gzdopen(fd, "rb");
  if (!z) {
    if (fd >= 0) close(fd);
    throw InputError(fmt::format("{}: cannot be read", shown));
  }
  std::string text(formats::kMaxHeaderBytes, '\0');
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
      return WriteScratch(out, options);
    }
    const std::string key = formats::nrrd::FieldName(line);
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

bool IsNrrd(const fs::path& path, const std::string& shown) {
  return file_checks::ReadHead(path, 4, shown) == "NRRD";
}

}  // namespace

namespace reader {

std::unique_ptr<VolumeRead> OpenVolumeFile(const fs::path& path, const std::vector<fs::path>& named,
                                           const ReadOptions& options) {
  const std::string& shown = options.shown;
  itk_image::InitToolkits();
  // The files the header names sit beside it when it names them so; any
  // other way (a subfolder, an absolute path, a list) gets a rewrite of the
  // header that names where the cage placed them.
  if (IsGzippedNrrd(path)) {
    const fs::path read = RewriteGzippedNrrd(path, options);
    try {
      return OpenWithItk(read, {path}, options);
    } catch (const itk::ExceptionObject& e) {
      throw InputError(fmt::format("{}: {}", shown, itk_image::ItkMessage(e, {path, read}, shown)));
    }
  }
  const formats::References refs = formats::FindReferences(path, shown);
  const bool beside = std::all_of(refs.files.begin(), refs.files.end(), [&](const fs::path& f) {
    return f.parent_path() == path.parent_path() && fs::exists(fs::symlink_status(f));
  });
  fs::path read = path;
  if (!refs.field.empty() && !beside && refs.field != "NIfTI/Analyze .hdr/.img pair") {
    read = IsNrrd(path, shown) ? RewriteNrrdHeader(path, named, false, options)
                               : RewriteMetaImageHeader(path, named, options);
  }
  std::vector<fs::path> placed = named;
  for (const fs::path& f : refs.files) {
    if (beside) placed.push_back(f);
  }
  try {
    try {
      return OpenWithItk(read, placed, options);
    } catch (const itk::ExceptionObject& e) {
      if (!IsSpaceWithSpacingsError(e)) throw;
      read = RewriteNrrdHeader(path, beside ? refs.files : named, true, options);
      return OpenWithItk(read, placed, options);
    }
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: {}", shown, itk_image::ItkMessage(e, {path, read}, shown)));
  }
}

}  // namespace reader
}  // namespace cinevol

// Volume files through ITK: NIfTI, NRRD/NHDR, MetaImage and VTK legacy.
#include <gdcmTrace.h>
#include <itkGDCMImageIOFactory.h>
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
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <map>
#include <mutex>
#include <random>
#include <regex>

#include <fmt/format.h>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/itk_image.h"
#include "io/volume_loader.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace itk_image {

// The formats are registered explicitly rather than through ITK's
// CMake-generated factory list, so the set is visible here.
void InitToolkits() {
  static std::once_flag once;
  std::call_once(once, [] {
    itk::NiftiImageIOFactory::RegisterOneFactory();
    itk::NrrdImageIOFactory::RegisterOneFactory();
    itk::MetaImageIOFactory::RegisterOneFactory();
    itk::VTKImageIOFactory::RegisterOneFactory();
    itk::GDCMImageIOFactory::RegisterOneFactory();
    itk::Object::GlobalWarningDisplayOff();
    gdcm::Trace::WarningOff();
    gdcm::Trace::DebugOff();
  });
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

Volume ToVolume(FloatImage* image, VolumeMetadata meta) {
  const auto size = image->GetLargestPossibleRegion().GetSize();
  const auto spacing = image->GetSpacing();
  const auto origin = image->GetOrigin();
  const auto direction = image->GetDirection();
  for (int r = 0; r < 3; ++r) {
    meta.origin_mm[r] = origin[r];
    for (int c = 0; c < 3; ++c) meta.direction[3 * r + c] = direction[r][c];
  }
  const float* pixels = image->GetBufferPointer();
  std::vector<float> values(pixels, pixels + image->GetPixelContainer()->Size());
  image->Initialize();  // frees ITK's copy before the Volume picks its storage
  return Volume({int(size[0]), int(size[1]), int(size[2])},
                {float(spacing[0]), float(spacing[1]), float(spacing[2])}, std::move(values),
                std::move(meta));
}

}  // namespace itk_image

namespace {

using itk_image::FloatImage;

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

// The copy of a header that the lenient NRRD reading writes, removed when done.
struct TempFile {
  fs::path path;
  ~TempFile() {
    std::error_code ec;
    if (!path.empty()) fs::remove(path, ec);
  }
};

// The lines teem skips before the voxels: a header's own `line skip` field.
std::int64_t LineSkip(const std::string& line, const std::string& shown) {
  const std::string value = line.substr(std::min(line.size(), line.find_first_not_of(" \t", line.find(':') + 1)));
  std::int64_t n = 0;
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
  if (ec != std::errc() || n < 0) throw InputError(fmt::format("{}: 'line skip' is not a count", shown));
  return n;
}

// Some published detached NRRD headers give both `space` and per-axis
// `spacings`, which teem (ITK's NRRD reader) rejects. The intent is plain:
// the spacings are the voxel size. Writes a copy of the header without the
// `space` line into `copy`. Its data file field names only the canonical
// files the original's check resolved (or the file itself, past its header
// lines, for attached voxels), so the copy reaches nothing the original could
// not: it never becomes a way around the LoadPolicy.
void WriteLenientNrrdHeader(const fs::path& header, const std::string& shown, TempFile& copy) {
  const file_checks::NrrdHeader h = file_checks::ParseNrrdHeader(header, shown);
  if (!h.references.problem.empty()) throw InputError(fmt::format("{}: {}", shown, h.references.problem));
  std::string out;
  std::int64_t line_skip = 0;
  for (const std::string& line : h.lines) {
    const std::string key = file_checks::FieldName(line);
    if (key == "space") continue;
    if (h.attached && key == "lineskip") {
      line_skip = LineSkip(line, shown);
      continue;
    }
    out += line + "\n";
  }
  std::vector<std::string> files;
  for (const fs::path& f : h.attached ? std::vector<fs::path>{header} : h.references.files) {
    std::error_code ec;
    const std::string real = fs::canonical(f, ec).string();
    if (ec || real.find_first_of("\r\n") != std::string::npos) {
      throw InputError(fmt::format("{}: the header's 'data file' names a file that cannot be read", shown));
    }
    files.push_back(real);
  }
  if (h.attached) out += fmt::format("line skip: {}\n", std::int64_t(h.line_count) + line_skip);
  if (h.listed) {
    out += "data file: LIST" + (h.list_dim.empty() ? "" : " " + h.list_dim) + "\n";
    for (const std::string& f : files) out += f + "\n";
  } else {
    out += "data file: " + files.at(0) + "\n";
  }
  std::random_device rd;
  copy.path = fs::temp_directory_path() / fmt::format("cinevol-{:08x}{:08x}.nhdr", rd(), rd());
  // "x": never through a file or link someone placed there first.
  std::FILE* f = std::fopen(copy.path.c_str(), "wx");
  const bool written = f && std::fwrite(out.data(), 1, out.size(), f) == out.size();
  if (f) std::fclose(f);
  if (!written) throw InputError(fmt::format("{}: cannot write a corrected copy of the header", shown));
}

bool IsSpaceWithSpacingsError(const itk::ExceptionObject& e) {
  return std::string(e.GetDescription()).find("ScalarWithSpace") != std::string::npos;
}

itk::ImageIOBase::Pointer ReadHeader(const fs::path& path, const std::string& shown) {
  itk_image::InitToolkits();
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  if (!io) {
    throw InputError(fmt::format(
        "{}: not a volume format cinevol reads (NIfTI, NRRD/NHDR, MetaImage, VTK; "
        "DICOM is read from a folder)",
        shown));
  }
  io->SetFileName(path.string());
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

// ITK's NIfTI reader pads a short payload with zeros instead of failing, so
// the payload is counted here first (gz or plain: zlib reads both). Returns
// "" when the file holds every voxel, else what is missing.
std::string NiftiPayloadProblem(const fs::path& path) {
  const int fd = file_checks::OpenRegularFile(path);
  gzFile f = fd < 0 ? nullptr : gzdopen(fd, "rb");
  if (!f) {
    if (fd >= 0) close(fd);
    return "cannot open";
  }
  struct Close {
    gzFile f;
    ~Close() { gzclose(f); }
  } close{f};
  union {
    nifti_1_header n1;
    nifti_2_header n2;
  } h;
  if (gzread(f, &h, sizeof(nifti_1_header)) != int(sizeof(nifti_1_header))) return "header is truncated";
  const bool swap = h.n1.sizeof_hdr != 348 && h.n1.sizeof_hdr != 540;
  const int header_size = swap ? Swapped(h.n1.sizeof_hdr) : h.n1.sizeof_hdr;
  std::int64_t voxels = 1, bitpix = 0, offset = 0;
  if (header_size == 348) {
    const int ndim = std::clamp<int>(swap ? Swapped(h.n1.dim[0]) : h.n1.dim[0], 1, 7);
    for (int i = 1; i <= ndim; ++i) voxels *= swap ? Swapped(h.n1.dim[i]) : h.n1.dim[i];
    bitpix = swap ? Swapped(h.n1.bitpix) : h.n1.bitpix;
    offset = std::int64_t(swap ? Swapped(h.n1.vox_offset) : h.n1.vox_offset);
  } else {
    const int rest = int(sizeof(nifti_2_header) - sizeof(nifti_1_header));
    if (gzread(f, reinterpret_cast<char*>(&h) + sizeof(nifti_1_header), rest) != rest) return "header is truncated";
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

// ITK's MetaImage and VTK readers warn about a short payload on stderr and
// carry on. For uncompressed data the file that holds the voxels must be at
// least as long as they are.
std::string RawPayloadProblem(itk::ImageIOBase& io, const fs::path& path) {
  fs::path data = path;
  if (auto* meta = dynamic_cast<itk::MetaImageIO*>(&io)) {
    const std::string file = meta->GetMetaImagePointer()->ElementDataFileName();
    if (meta->GetMetaImagePointer()->CompressedData() || file == "LIST" || file.find('%') != std::string::npos ||
        file.find(' ') != std::string::npos) {
      return "";
    }
    if (file != "LOCAL") data = fs::path(file).is_absolute() ? fs::path(file) : path.parent_path() / file;
  } else if (std::string(io.GetNameOfClass()) != "VTKImageIO" || io.GetFileType() != itk::IOFileEnum::Binary) {
    return "";
  }
  std::error_code ec;
  const auto size = file_checks::IsRegularFile(data) ? fs::file_size(data, ec) : 0;
  if (ec || !file_checks::IsRegularFile(data)) return "cannot read the file that ElementDataFile names";
  if (size < std::uintmax_t(io.GetImageSizeInBytes())) {
    return fmt::format("truncated: {} voxel bytes expected, {} holds {} bytes in all", io.GetImageSizeInBytes(),
                       data == path ? "the file" : "'" + data.filename().string() + "'", size);
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

// MetaIO parsed the header on its own: what it will open must be what the
// header check found (a single file is checked again, a list or pattern must
// have been seen).
void CheckMetaImageDataFile(itk::ImageIOBase& io, const fs::path& path, const file_checks::References& checked,
                            const LoadPolicy& policy, const std::string& shown) {
  auto* meta = dynamic_cast<itk::MetaImageIO*>(&io);
  if (!meta) return;
  const std::string name = meta->GetMetaImagePointer()->ElementDataFileName();
  if (name == "LOCAL" || name == "Local" || name == "local") return;
  file_checks::References refs{"ElementDataFile", {}, ""};
  if (name.rfind("LIST", 0) == 0 || name.find('%') != std::string::npos) {
    if (!checked.field.empty()) return;
    refs.problem = "a form the header check did not see";
  } else {
    refs.files.push_back(!name.empty() && name[0] == '/' ? fs::path(name) : path.parent_path() / name);
  }
  file_checks::CheckReferences(refs, policy, shown);
}

// Reads `path` (the named file, or the lenient copy of its header) whose
// references were checked as `refs`.
Volume ReadWithItk(const fs::path& path, const file_checks::References& refs, const LoadPolicy& policy,
                   const std::string& shown) {
  auto io = ReadHeader(path, shown);
  CheckHeader(shown, *io, policy.max_voxels);
  CheckMetaImageDataFile(*io, path, refs, policy, shown);
  const std::string problem = std::string(io->GetNameOfClass()) == "NiftiImageIO"
                                  ? NiftiPayloadProblem(path)
                                  : RawPayloadProblem(*io, path);
  if (!problem.empty()) throw InputError(fmt::format("{}: {}", shown, problem));
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path.string());
  reader->Update();

  VolumeMetadata meta;
  meta.source = shown;
  meta.original_type = OriginalType(*io);
  meta.modality = MetaImageModality(*io);
  if (meta.modality == "CT") meta.value_unit = "HU";
  return itk_image::ToVolume(reader->GetOutput(), std::move(meta));
}

}  // namespace

Volume LoadVolumeFile(const fs::path& path, const LoadPolicy& policy) {
  const std::string shown = file_checks::Shown(path, policy);
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw InputError(fmt::format("{}: no such file", shown));
  if (fs::is_directory(status)) return LoadDicomSeries(path, {}, policy);
  file_checks::RequireRegularFile(path, shown);
  file_checks::RequireInsideRoots(path, policy, shown);
  // Before ITK opens anything: the files the header names.
  const file_checks::References refs = file_checks::FindReferences(path, shown);
  file_checks::CheckReferences(refs, policy, shown);
  TempFile copy;
  try {
    try {
      return ReadWithItk(path, refs, policy, shown);
    } catch (const itk::ExceptionObject& e) {
      if (!IsSpaceWithSpacingsError(e)) throw;
      spdlog::warn("{}: NRRD header gives both 'space' and 'spacings'; using the spacings", path.string());
      WriteLenientNrrdHeader(path, shown, copy);
      return ReadWithItk(copy.path, refs, policy, shown);
    }
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: {}", shown, itk_image::ItkMessage(e, {path, copy.path}, shown)));
  } catch (const std::bad_alloc&) {
    throw InputError(fmt::format("{}: out of memory reading the volume", shown));
  }
}

}  // namespace cinevol

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

#include <algorithm>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
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

// ITK messages start with "file:line:\nITK ERROR: Class(0x...): "; keep the rest.
std::string ShortItkMessage(const itk::ExceptionObject& e) {
  std::string d = e.GetDescription();
  const auto colon = d.find("): ");
  if (d.rfind("ITK ERROR", 0) == 0 && colon != std::string::npos) d = d.substr(colon + 3);
  while (!d.empty() && (d.back() == '\n' || d.back() == ' ')) d.pop_back();
  return d;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Some published detached NRRD headers give both `space` and per-axis
// `spacings`, which teem (ITK's NRRD reader) rejects. The intent is plain:
// the spacings are the voxel size. Writes a copy of the header without the
// `space` line and with data file paths made absolute; returns its path.
fs::path WriteLenientNrrdHeader(const fs::path& header) {
  const fs::path dir = fs::absolute(header).parent_path();
  std::istringstream in(ReadText(header));
  std::ostringstream out;
  bool in_file_list = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("space:", 0) == 0) continue;
    if (in_file_list && !line.empty()) {
      out << (fs::path(line).is_absolute() ? fs::path(line) : dir / line).string() << '\n';
      continue;
    }
    const std::string key = "data file:";
    if (line.rfind(key, 0) == 0) {
      std::string rest = line.substr(key.size());
      rest.erase(0, rest.find_first_not_of(' '));
      in_file_list = rest.rfind("LIST", 0) == 0;
      if (!in_file_list && !fs::path(rest).is_absolute()) rest = (dir / rest).string();
      line = key + " " + rest;
    }
    out << line << '\n';
  }
  std::random_device rd;
  const fs::path copy = fs::temp_directory_path() / fmt::format("cinevol-{:x}.nhdr", rd());
  std::ofstream(copy) << out.str();
  return copy;
}

bool IsSpaceWithSpacingsError(const itk::ExceptionObject& e) {
  return std::string(e.GetDescription()).find("ScalarWithSpace") != std::string::npos;
}

itk::ImageIOBase::Pointer ReadHeader(const fs::path& path) {
  itk_image::InitToolkits();
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  if (!io) {
    throw InputError(fmt::format(
        "{}: not a volume format cinevol reads (NIfTI, NRRD/NHDR, MetaImage, VTK; "
        "DICOM is read from a folder)",
        path.string()));
  }
  io->SetFileName(path.string());
  io->ReadImageInformation();
  return io;
}

void CheckHeader(const fs::path& path, itk::ImageIOBase& io) {
  const unsigned dims = io.GetNumberOfDimensions();
  if (dims < 2 || dims > 3) {
    throw InputError(fmt::format("{}: a {}-D image; cinevol reads 2-D and 3-D scalar volumes",
                                 path.string(), dims));
  }
  if (io.GetNumberOfComponents() != 1) {
    throw InputError(fmt::format("{}: {} components per voxel ({}); cinevol needs one scalar",
                                 path.string(), io.GetNumberOfComponents(),
                                 io.GetPixelTypeAsString(io.GetPixelType())));
  }
  if (!IsSupportedComponent(io.GetComponentType())) {
    throw InputError(fmt::format("{}: unsupported voxel type '{}'", path.string(),
                                 io.GetComponentTypeAsString(io.GetComponentType())));
  }
  Vec3i size{1, 1, 1};
  Vec3f spacing{1, 1, 1};
  for (unsigned a = 0; a < dims; ++a) {
    // Sizes past int range are absurd; clamp so the check below names them.
    size[a] = int(std::min<itk::SizeValueType>(io.GetDimensions(a), 1u << 30));
    spacing[a] = float(io.GetSpacing(a));
  }
  CheckVolumeGeometry(size, spacing, path.string());
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

// ITK's NIfTI reader pads a short payload with zeros instead of failing, so
// the payload is counted here first (gz or plain: zlib reads both). Returns
// "" when the file holds every voxel, else what is missing.
std::string NiftiPayloadProblem(const fs::path& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return "cannot open";
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
  const std::int64_t expected = offset + voxels * bitpix / 8;
  std::int64_t total = header_size == 348 ? sizeof(nifti_1_header) : sizeof(nifti_2_header);
  std::vector<char> buffer(1 << 20);
  for (int n; (n = gzread(f, buffer.data(), unsigned(buffer.size()))) > 0;) total += n;
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
  const auto size = fs::file_size(data, ec);
  if (ec) return fmt::format("cannot read the voxel data file {}", data.string());
  if (size < std::uintmax_t(io.GetImageSizeInBytes())) {
    return fmt::format("truncated: {} voxel bytes expected, {} holds {} bytes in all", io.GetImageSizeInBytes(),
                       data.filename().string(), size);
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

Volume ReadWithItk(const fs::path& path, const fs::path& source) {
  auto io = ReadHeader(path);
  CheckHeader(source, *io);
  const std::string problem = std::string(io->GetNameOfClass()) == "NiftiImageIO"
                                  ? NiftiPayloadProblem(path)
                                  : RawPayloadProblem(*io, path);
  if (!problem.empty()) throw InputError(fmt::format("{}: {}", source.string(), problem));
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path.string());
  reader->Update();

  VolumeMetadata meta;
  meta.source = source.string();
  meta.original_type = OriginalType(*io);
  meta.modality = MetaImageModality(*io);
  if (meta.modality == "CT") meta.value_unit = "HU";
  return itk_image::ToVolume(reader->GetOutput(), std::move(meta));
}

}  // namespace

Volume LoadVolumeFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(fmt::format("{}: no such file", path.string()));
  if (fs::is_directory(path, ec)) return LoadDicomSeries(path);
  try {
    try {
      return ReadWithItk(path, path);
    } catch (const itk::ExceptionObject& e) {
      if (!IsSpaceWithSpacingsError(e)) throw;
      spdlog::warn("{}: NRRD header gives both 'space' and 'spacings'; using the spacings",
                   path.string());
      const fs::path copy = WriteLenientNrrdHeader(path);
      struct Remove {
        fs::path p;
        ~Remove() { fs::remove(p); }
      } remove{copy};
      return ReadWithItk(copy, path);
    }
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: {}", path.string(), ShortItkMessage(e)));
  } catch (const std::bad_alloc&) {
    throw InputError(fmt::format("{}: out of memory reading the volume", path.string()));
  }
}

}  // namespace cinevol

// Volume files through ITK: NIfTI, NRRD/NHDR, MetaImage and VTK legacy.
#include <itkGDCMImageIOFactory.h>
#include <itkImageFileReader.h>
#include <itkImageIOFactory.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIOFactory.h>
#include <itkVTKImageIOFactory.h>
#include <spdlog/spdlog.h>

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

// The formats cinevol accepts, registered explicitly rather than through
// ITK's CMake-generated factory list, so the set is visible here.
void RegisterImageIOs() {
  static std::once_flag once;
  std::call_once(once, [] {
    itk::NiftiImageIOFactory::RegisterOneFactory();
    itk::NrrdImageIOFactory::RegisterOneFactory();
    itk::MetaImageIOFactory::RegisterOneFactory();
    itk::VTKImageIOFactory::RegisterOneFactory();
    itk::GDCMImageIOFactory::RegisterOneFactory();
  });
}

itk::ImageIOBase::Pointer ReadHeader(const fs::path& path) {
  RegisterImageIOs();
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

Volume ReadWithItk(const fs::path& path, const fs::path& source) {
  auto io = ReadHeader(path);
  CheckHeader(source, *io);
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path.string());
  reader->Update();

  VolumeMetadata meta;
  meta.source = source.string();
  meta.original_type = OriginalType(*io);
  const std::string modality = MetaString(io->GetMetaDataDictionary(), "Modality");
  if (modality == "MET_MOD_CT" || modality == "CT") meta.modality = "CT";
  if (modality == "MET_MOD_MR" || modality == "MR") meta.modality = "MR";
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

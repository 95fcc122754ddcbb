// Volume files through ITK: NIfTI, NRRD/NHDR, MetaImage and VTK legacy, each
// with its format's checks (io/formats/) around ITK's ImageIO.
#include <gdcmGlobal.h>
#include <gdcmTrace.h>
#include <itkGDCMImageIO.h>
#include <itkImageIOBase.h>
#include <itkImageIOFactory.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIOFactory.h>
#include <itkVTKImageIOFactory.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <regex>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"
#include "io/formats/format.h"
#include "io/formats/metaimage/checks.h"
#include "io/formats/nifti/checks.h"
#include "io/formats/nrrd/checks.h"
#include "io/formats/nrrd/references.h"
#include "io/formats/vtk/checks.h"
#include "io/readers/formats.h"
#include "io/readers/itk_image.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace itk_image {

// The formats are registered explicitly rather than through ITK's
// CMake-generated factory list, so the set is visible here. GDCM is not among
// them: DICOM is read from a folder (dicom_series.cpp makes its GDCMImageIO
// after the DICOM checks), and the factory would have GDCM parse
// any file the other formats decline (GDCM asserts, aborting, on a malformed
// meta group).
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

using itk_image::ComponentName;
using itk_image::ItkMessage;
using itk_image::SetGeometry;
using itk_image::VoxelTypeOf;

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

// Replaces the scratch file's text with `text`; returns its path.
fs::path WriteScratch(const std::string& text, const reader::ReadOptions& options) {
  if (options.scratch_fd < 0 || ftruncate(options.scratch_fd, 0) != 0 ||
      pwrite(options.scratch_fd, text.data(), text.size(), 0) != ssize_t(text.size())) {
    throw InputError(fmt::format("{}: cannot rewrite the header ({} bytes)", options.shown, text.size()));
  }
  return options.scratch_path;
}

// The format of the ImageIO ITK chose for a file.
formats::Format FormatOf(const itk::ImageIOBase& io) {
  const std::string kind = io.GetNameOfClass();
  return kind == "NiftiImageIO"  ? formats::Format::kNifti
         : kind == "NrrdImageIO" ? formats::Format::kNrrd
         : kind == "MetaImageIO" ? formats::Format::kMetaImage
         : kind == "VTKImageIO"  ? formats::Format::kVtk
                                 : formats::Format::kUnknown;
}

// The ImageIO ITK chooses for `path`, its header read after its format's
// checks of the header's text.
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
  if (prechecks && FormatOf(*io) == formats::Format::kMetaImage) formats::metaimage::CheckHeaderText(path, shown);
  if (prechecks && FormatOf(*io) == formats::Format::kNrrd) formats::nrrd::CheckHeaderText(path, shown);
  io->ReadImageInformation();
  return io;
}

// Throws InputError unless the header describes what cinevol reads: a 2-D or
// 3-D scalar image of a known type, within the geometry and voxel limits.
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

// A volume file opened through ITK: the header read and checked, the voxels
// not yet.
class ItkVolumeRead final : public reader::VolumeRead {
 public:
  ItkVolumeRead(itk::ImageIOBase::Pointer io, const fs::path& path, const reader::ReadOptions& options)
      : io_(std::move(io)), format_(FormatOf(*io_)), path_(path), shown_(options.shown),
        prechecks_(options.prechecks) {
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
    SetGeometry(header_, dims, spacing, origin, direction);
    header_.set_voxel_type(VoxelTypeOf(io_->GetComponentType()));
    // The type as stored in the file: NIfTI's datatype where ITK converts.
    const std::string stored = formats::nifti::StoredType(*io_);
    header_.set_original_type(stored.empty() ? ComponentName(io_->GetComponentType()) : stored);
    header_.set_modality(format_ == formats::Format::kMetaImage ? formats::metaimage::Modality(*io_) : "");
    if (header_.modality() == "CT") header_.set_value_unit("HU");
  }

  void Read(void* memory, std::size_t bytes) override {
    // The payload is checked now, once the parent has counted the memory the
    // header asks for: a small compressed file may inflate to gigabytes.
    if (prechecks_) {
      const std::string problem = PayloadProblem();
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
      throw InputError(fmt::format("{}: {}", shown_, ItkMessage(e, {io_->GetFileName()}, shown_)));
    }
  }

 private:
  // The format's check that the file holds every voxel, as its reader reads
  // them: "" or what is wrong.
  std::string PayloadProblem() {
    switch (format_) {
      case formats::Format::kNifti: return formats::nifti::PayloadProblem(path_);
      case formats::Format::kNrrd: return formats::nrrd::PayloadProblem(*io_, path_, shown_);
      case formats::Format::kMetaImage: return formats::metaimage::PayloadProblem(*io_, path_, shown_);
      case formats::Format::kVtk: return formats::vtk::PayloadProblem(*io_, path_);
      default: return "";
    }
  }

  itk::ImageIOBase::Pointer io_;
  formats::Format format_;
  fs::path path_;
  std::string shown_;
  bool prechecks_;
};

// Opens `path` (the file, or the cage's rewrite of its header) with ITK.
std::unique_ptr<reader::VolumeRead> OpenWithItk(const fs::path& path, const std::vector<fs::path>& placed,
                                                const reader::ReadOptions& options) {
  const std::string& shown = options.shown;
  if (options.prechecks) formats::nifti::CheckHeaders(path, shown);  // ITK parses it to choose
  auto io = ReadHeader(path, shown, options.prechecks);
  CheckHeader(shown, *io, options.max_voxels);
  if (FormatOf(*io) == formats::Format::kMetaImage) formats::metaimage::CheckDataFile(*io, path, placed, shown);
  return std::make_unique<ItkVolumeRead>(io, path, options);
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
  if (formats::nrrd::IsGzipped(path)) {
    const fs::path read = WriteScratch(formats::nrrd::GzippedRewrite(path, shown), options);
    try {
      return OpenWithItk(read, {path}, options);
    } catch (const itk::ExceptionObject& e) {
      throw InputError(fmt::format("{}: {}", shown, ItkMessage(e, {path, read}, shown)));
    }
  }
  const formats::References refs = formats::FindReferences(path, shown);
  const bool beside = std::all_of(refs.files.begin(), refs.files.end(), [&](const fs::path& f) {
    return f.parent_path() == path.parent_path() && fs::exists(fs::symlink_status(f));
  });
  fs::path read = path;
  if (!refs.field.empty() && !beside && refs.field != "NIfTI/Analyze .hdr/.img pair") {
    read = WriteScratch(formats::nrrd::HasMagic(path, shown) ? formats::nrrd::RewrittenHeader(path, named, false, shown)
                                                             : formats::metaimage::RewrittenHeader(path, named, shown),
                        options);
  }
  std::vector<fs::path> placed = named;
  for (const fs::path& f : refs.files) {
    if (beside) placed.push_back(f);
  }
  try {
    try {
      return OpenWithItk(read, placed, options);
    } catch (const itk::ExceptionObject& e) {
      if (!formats::nrrd::IsSpaceWithSpacingsError(e.GetDescription())) throw;
      read = WriteScratch(formats::nrrd::RewrittenHeader(path, beside ? refs.files : named, true, shown), options);
      return OpenWithItk(read, placed, options);
    }
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: {}", shown, ItkMessage(e, {path, read}, shown)));
  }
}

}  // namespace reader
}  // namespace cinevol

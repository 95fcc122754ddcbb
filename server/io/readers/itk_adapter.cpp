// The ITK/GDCM adapter: the one place that drives ITK's ImageIO (NIfTI, NRRD,
// MetaImage, VTK) and GDCM (DICOM), with each format's checks around it
// (io/formats/), and that converts what they decode, once, into the voxel
// block the parent receives, in the file's native type.
#include "io/readers/itk_adapter.h"

#include <fmt/format.h>
#include <gdcmGlobal.h>
#include <gdcmImageReader.h>
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
#include <cstring>
#include <mutex>
#include <regex>
#include <vector>

#include "core/error.h"
#include "core/volume.h"
#include "core/voxel_memory.h"
#include "io/formats/dicom/series.h"
#include "io/formats/format.h"
#include "io/formats/metaimage/checks.h"
#include "io/formats/nifti/checks.h"
#include "io/formats/nrrd/checks.h"
#include "io/formats/nrrd/references.h"
#include "io/formats/vtk/checks.h"
#include "io/readers/volume_read.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace dicom = formats::dicom;
namespace metaimage = formats::metaimage;
namespace nifti = formats::nifti;
namespace nrrd = formats::nrrd;
namespace vtk = formats::vtk;
using formats::Format;

namespace itk_adapter {

// The formats are registered explicitly rather than through ITK's
// CMake-generated factory list, so the set is visible here. GDCM is not among
// them: DICOM is read from a folder (DicomSeriesRead below makes its
// GDCMImageIO after the DICOM checks), and the factory would have GDCM parse
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

}  // namespace itk_adapter

namespace {

// "int16", "uint8", "float32", ... for a file's voxel type.
std::string ComponentName(itk::IOComponentEnum type) {
  using C = itk::IOComponentEnum;
  switch (type) {
    case C::UCHAR:
      return "uint8";
    case C::CHAR:
      return "int8";
    case C::USHORT:
      return "uint16";
    case C::SHORT:
      return "int16";
    case C::UINT:
      return "uint32";
    case C::INT:
      return "int32";
    case C::ULONG:
    case C::ULONGLONG:
      return "uint64";
    case C::LONG:
    case C::LONGLONG:
      return "int64";
    case C::FLOAT:
      return "float32";
    case C::DOUBLE:
      return "float64";
    default:
      return itk::ImageIOBase::GetComponentTypeAsString(type);
  }
}

// ITK's message without its source location and class prefix ("file.cxx:123:
// ITK ERROR: Class(0x...): "), with each of `paths` replaced by `shown`: ITK,
// teem and GDCM quote the paths they open, and messages must not.
std::string ItkMessage(const itk::ExceptionObject& e, const std::vector<fs::path>& paths, const std::string& shown) {
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

// The VoxelType name (core/voxel_memory.h) of an ITK component; "" for one
// cinevol does not read.
std::string VoxelTypeOf(itk::IOComponentEnum type) {
  const std::string name = ComponentName(type);
  return VoxelTypeNamed(name) ? name : "";
}

// Sets `header`'s grid: `direction` row-major, column c is index axis c.
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
  const double det =
      d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) + d[2] * (d[3] * d[7] - d[4] * d[6]);
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

// "unknown" ITK enum values print as numbers; name the ones cinevol accepts.
bool IsSupportedComponent(itk::IOComponentEnum c) {
  using C = itk::IOComponentEnum;
  switch (c) {
    case C::UCHAR:
    case C::CHAR:
    case C::USHORT:
    case C::SHORT:
    case C::UINT:
    case C::INT:
    case C::ULONG:
    case C::LONG:
    case C::ULONGLONG:
    case C::LONGLONG:
    case C::FLOAT:
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
Format FormatOf(const itk::ImageIOBase& io) {
  const std::string kind = io.GetNameOfClass();
  return kind == "NiftiImageIO"  ? Format::kNifti
         : kind == "NrrdImageIO" ? Format::kNrrd
         : kind == "MetaImageIO" ? Format::kMetaImage
         : kind == "VTKImageIO"  ? Format::kVtk
                                 : Format::kUnknown;
}

// The ImageIO ITK chooses for `path`, its header read after its format's
// checks of the header's text.
itk::ImageIOBase::Pointer ReadHeader(const fs::path& path, const std::string& shown, bool prechecks) {
  itk_adapter::InitToolkits();
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  if (!io) {
    throw InputError(
        fmt::format("{}: not a volume format cinevol reads (NIfTI, NRRD/NHDR, MetaImage, VTK; "
                    "DICOM is read from a folder)",
                    shown));
  }
  io->SetFileName(path.string());
  if (prechecks && FormatOf(*io) == Format::kMetaImage) metaimage::CheckHeaderText(path, shown);
  if (prechecks && FormatOf(*io) == Format::kNrrd) nrrd::CheckHeaderText(path, shown);
  io->ReadImageInformation();
  return io;
}

// Throws InputError unless the header describes what cinevol reads: a 2-D or
// 3-D scalar image of a known type, or a time series of 3-D ones (a 4-D
// image: NIfTI's fourth dimension, an NRRD time axis), within the geometry
// and voxel limits, every phase counted.
void CheckHeader(const std::string& shown, itk::ImageIOBase& io, std::uint64_t max_voxels) {
  const unsigned dims = io.GetNumberOfDimensions();
  if (dims < 2 || dims > 4) {
    throw InputError(
        fmt::format("{}: a {}-D image; cinevol reads 2-D and 3-D scalar volumes and time series of "
                    "3-D ones (4-D)",
                    shown, dims));
  }
  if (io.GetNumberOfComponents() != 1) {
    throw InputError(fmt::format("{}: {} components per voxel ({}); cinevol needs one scalar", shown,
                                 io.GetNumberOfComponents(), io.GetPixelTypeAsString(io.GetPixelType())));
  }
  if (!IsSupportedComponent(io.GetComponentType())) {
    throw InputError(
        fmt::format("{}: unsupported voxel type '{}'", shown, io.GetComponentTypeAsString(io.GetComponentType())));
  }
  Vec3i size{1, 1, 1};
  Vec3f spacing{1, 1, 1};
  for (unsigned a = 0; a < std::min(dims, 3u); ++a) {  // a fourth is time
    // Sizes past int range are absurd; clamp so the check below names them.
    size[a] = int(std::min<itk::SizeValueType>(io.GetDimensions(a), 1u << 30));
    spacing[a] = float(io.GetSpacing(a));
  }
  CheckVolumeGeometry(size, spacing, shown);
  const std::uint64_t phases = dims == 4 ? io.GetDimensions(3) : 1;
  if (phases < 1 || phases > std::uint64_t(kMaxPhases)) {
    throw InputError(fmt::format("{}: a time series of {} phases; cinevol reads 1 to {}", shown, phases, kMaxPhases));
  }
  CheckVoxelLimit(size, phases, max_voxels, shown);
}

// A volume file opened through ITK: the header read and checked, the voxels
// not yet.
class ItkVolumeRead final : public reader::VolumeRead {
 public:
  ItkVolumeRead(itk::ImageIOBase::Pointer io, const fs::path& path, const reader::ReadOptions& options)
      : io_(std::move(io)), format_(FormatOf(*io_)), path_(path), shown_(options.shown), prechecks_(options.prechecks) {
    const unsigned n = std::min(io_->GetNumberOfDimensions(), 3u);  // a fourth is time
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
    if (io_->GetNumberOfDimensions() == 4 && io_->GetDimensions(3) > 1) SetPhases();
    if (!StatesOrientation()) {
      std::array<double, 9> held;
      std::copy(header_.direction().begin(), header_.direction().end(), held.begin());
      header_.add_notes(
          fmt::format("the file states no orientation: its index axes are taken as {} (--orientation "
                      "gives the true one)",
                      OrientationCode(held)));
    }
    header_.set_voxel_type(VoxelTypeOf(io_->GetComponentType()));
    // The type as stored in the file: NIfTI's datatype where ITK converts.
    const std::string stored = nifti::StoredType(*io_);
    header_.set_original_type(stored.empty() ? ComponentName(io_->GetComponentType()) : stored);
    header_.set_modality(format_ == Format::kMetaImage ? metaimage::Modality(*io_) : "");
    if (header_.modality() == "CT") header_.set_value_unit("HU");
  }

  // A 4-D image's fourth axis as phases, a spacing along it (ITK's, in
  // seconds: NIfTI's pixdim[4] in its time unit) as their times.
  void SetPhases() {
    header_.set_phases(std::uint32_t(io_->GetDimensions(3)));
    const double step = io_->GetSpacing(3);
    if (!(std::isfinite(step) && step > 0 && step < 1e6)) {
      header_.add_notes("a time series whose file gives no time between its phases");
      return;
    }
    for (std::uint32_t k = 0; k < header_.phases(); ++k) header_.add_phase_seconds(k * step);
  }

  // Whether the file says where its axes point; where not, the direction the
  // reader gives is an assumption, which the header notes.
  bool StatesOrientation() const {
    switch (format_) {
      case Format::kNifti:
        return nifti::StatesOrientation(path_);
      case Format::kNrrd:
        return nrrd::StatesOrientation(path_, shown_);
      case Format::kMetaImage:
        return metaimage::StatesOrientation(path_, shown_);
      default:
        return false;  // VTK legacy structured points have no orientation
    }
  }

  // A still volume straight into `memory`; a time series whole into the
  // child's own memory with the first phase, each phase copied out of it.
  void Read(void* memory, std::size_t bytes, int phase) override {
    const std::size_t phase_bytes = std::size_t(io_->GetImageSizeInBytes()) / std::size_t(phases());
    if (bytes != phase_bytes) {
      throw InputError(fmt::format("{}: {} bytes of memory for {} bytes of voxels", shown_, bytes, phase_bytes));
    }
    if (phases() == 1) return ReadAll(memory);
    if (phase == 0) {
      all_phases_.resize(std::size_t(io_->GetImageSizeInBytes()));
      ReadAll(all_phases_.data());
    }
    std::memcpy(memory, all_phases_.data() + std::size_t(phase) * phase_bytes, phase_bytes);
    if (phase + 1 == phases()) std::vector<char>().swap(all_phases_);
  }

 private:
  // Every voxel of the file into `memory`, after the payload's check: now,
  // once the parent has counted the memory the header asks for (a small
  // compressed file may inflate to gigabytes).
  void ReadAll(void* memory) {
    if (prechecks_) {
      const std::string problem = PayloadProblem();
      if (!problem.empty()) throw InputError(fmt::format("{}: {}", shown_, problem));
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

  // The format's check that the file holds every voxel, as its reader reads
  // them: "" or what is wrong.
  std::string PayloadProblem() {
    switch (format_) {
      case Format::kNifti:
        return nifti::PayloadProblem(path_);
      case Format::kNrrd:
        return nrrd::PayloadProblem(*io_, path_, shown_);
      case Format::kMetaImage:
        return metaimage::PayloadProblem(*io_, path_, shown_);
      case Format::kVtk:
        return vtk::PayloadProblem(*io_, path_);
      default:
        return "";
    }
  }

  itk::ImageIOBase::Pointer io_;
  Format format_;
  fs::path path_;
  std::string shown_;
  bool prechecks_;
  std::vector<char> all_phases_;  // a time series' voxels, from the first phase's read to the last's
};

// Opens `path` (the file, or the cage's rewrite of its header) with ITK.
std::unique_ptr<reader::VolumeRead> OpenWithItk(const fs::path& path, const std::vector<fs::path>& placed,
                                                const reader::ReadOptions& options) {
  const std::string& shown = options.shown;
  if (options.prechecks) nifti::CheckHeaders(path, shown);  // ITK parses it to choose
  auto io = ReadHeader(path, shown, options.prechecks);
  CheckHeader(shown, *io, options.max_voxels);
  if (FormatOf(*io) == Format::kMetaImage) metaimage::CheckDataFile(*io, path, placed, shown);
  return std::make_unique<ItkVolumeRead>(io, path, options);
}

// Converts `n` values of ITK component `from` at `in` to float32 at `out`.
void ToFloat(itk::IOComponentEnum from, const void* in, float* out, std::size_t n) {
  using C = itk::IOComponentEnum;
  auto copy = [&](auto* typed) {
    for (std::size_t i = 0; i < n; ++i) out[i] = float(typed[i]);
  };
  switch (from) {
    case C::UCHAR:
      copy(static_cast<const std::uint8_t*>(in));
      break;
    case C::CHAR:
      copy(static_cast<const std::int8_t*>(in));
      break;
    case C::USHORT:
      copy(static_cast<const std::uint16_t*>(in));
      break;
    case C::SHORT:
      copy(static_cast<const std::int16_t*>(in));
      break;
    case C::UINT:
      copy(static_cast<const std::uint32_t*>(in));
      break;
    case C::INT:
      copy(static_cast<const std::int32_t*>(in));
      break;
    case C::FLOAT:
      copy(static_cast<const float*>(in));
      break;
    case C::DOUBLE:
      copy(static_cast<const double*>(in));
      break;
    default:
      throw InputError("a slice of a voxel type cinevol does not read");
  }
}

// One series, its slices sorted and its header known; the pixels are
// decoded slice by slice (GDCM: JPEG 2000 and other compressed transfer
// syntaxes included; rescale slope and intercept applied), or, for an
// enhanced multi-frame file, frame by frame from the file decoded whole. A
// time series (several slices at each position) is read a phase at a time,
// each phase's slices on the first phase's grid.
class DicomSeriesRead final : public reader::VolumeRead {
 public:
  DicomSeriesRead(const dicom::SortedSeries& series, std::uint64_t max_voxels)
      : where_(series.shown), series_(series.info), phase_slices_(series.phases) {
    const dicom::SeriesGeometry& g = series.geometry;
    auto io = itk::GDCMImageIO::New();
    try {
      // Header sizes are checked before decoding: absurd rows/columns never allocate.
      io->SetFileName(phase_slices_[0][0].file);
      io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
      throw Failed(e);
    }
    if (io->GetNumberOfComponents() != 1) {
      throw InputError(fmt::format("{}: series {} holds pixels of {} components; cinevol reads grey-scale series",
                                   where_, dicom::Describe(series_), io->GetNumberOfComponents()));
    }
    const std::uint64_t file_frames =
        io->GetNumberOfDimensions() > 2 ? std::max<std::uint64_t>(1, io->GetDimensions(2)) : 1;
    if (series.multi_frame) {
      frame_count_ = phase_slices_.size() * phase_slices_[0].size();
      if (file_frames != frame_count_) {
        throw InputError(fmt::format("{}: series {} holds {} frames where its functional groups describe {}",
                                     where_, dicom::Describe(series_), file_frames, frame_count_));
      }
    } else if (file_frames > 1 && (phase_slices_.size() > 1 || phase_slices_[0].size() > 1)) {
      throw InputError(
          fmt::format("{}: series {} has multi-frame files; cinevol reads one such file, or single-frame "
                      "slices",
                      where_, dicom::Describe(series_)));
    }
    // The frames a slice holds: a file without functional groups is one stack.
    const std::uint64_t frames = series.multi_frame ? 1 : file_frames;
    const std::array<double, 2> pixel_mm = g.pixel_spacing_mm[0] > 0
                                               ? g.pixel_spacing_mm
                                               : std::array<double, 2>{io->GetSpacing(0), io->GetSpacing(1)};
    const std::array<int, 3> dims{int(std::min<std::uint64_t>(io->GetDimensions(0), 1u << 30)),
                                  int(std::min<std::uint64_t>(io->GetDimensions(1), 1u << 30)),
                                  int(std::min<std::uint64_t>(g.GridSlices() * frames, 1u << 30))};
    CheckVolumeGeometry({dims[0], dims[1], dims[2]}, {float(pixel_mm[0]), float(pixel_mm[1]), float(g.slice_gap_mm)},
                        where_);
    CheckVoxelLimit({dims[0], dims[1], dims[2]}, phase_slices_.size(), max_voxels,
                    where_);  // phases: at most kMaxPhases
    // Geometry from the sorted positions, not from the first two files.
    std::array<double, 9> direction;
    for (int r = 0; r < 3; ++r) {
      direction[3 * r + 0] = g.row[r];
      direction[3 * r + 1] = g.col[r];
      direction[3 * r + 2] = g.normal[r];
    }
    const dicom::Slice& first = g.slices.front();
    SetGeometry(header_, dims, {pixel_mm[0], pixel_mm[1], g.slice_gap_mm},
                {first.position[0], first.position[1], first.position[2]}, direction);
    // A multi-frame file's frames are rescaled here, each by its own; other
    // files as GDCM rescales them.
    type_ = series.multi_frame ? io->GetInternalComponentType() : io->GetComponentType();
    const double slope = series.multi_frame ? first.rescale_slope : io->GetRescaleSlope();
    const double intercept = series.multi_frame ? first.rescale_intercept : io->GetRescaleIntercept();
    rescaled_alike_ = series.rescaled_alike && (!series.multi_frame || (slope == 1.0 && intercept == 0.0));
    header_.set_voxel_type(rescaled_alike_ ? VoxelTypeOf(type_) : "float32");
    if (header_.voxel_type().empty()) {
      throw InputError(fmt::format("{}: series {} holds voxels of type {}, which cinevol does not read", where_,
                                   dicom::Describe(series_), ComponentName(type_)));
    }
    header_.set_modality(series.modality);
    header_.set_value_unit(header_.modality() == "CT" ? "HU" : "");
    *header_.mutable_identity() = series.identity;
    for (double v : series.stored_window) header_.add_stored_window(v);
    header_.set_frame_of_reference_uid(series.frame_of_reference_uid);
    if (series.pet) *header_.mutable_pet() = *series.pet;
    std::string original = ComponentName(io->GetInternalComponentType());
    if (!series.rescaled_alike && series.multi_frame) {
      original += " (each frame rescaled by its own slope and intercept)";
    } else if (slope != 1.0 || intercept != 0.0) {
      original += fmt::format(" (rescale slope {:g}, intercept {:g})", slope, intercept);
    }
    header_.set_original_type(original);
    slice_voxels_ = std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(frames);
    if (g.tilt_deg > dicom::kMaxTiltDeg) Shear(g, pixel_mm[0], pixel_mm[1], dims);
    if (g.uneven) Even(g);
    if (phase_slices_.size() > 1) SetPhases(series);
  }

  // Phase `phase`'s slices, decoded into `memory` (resampled as the first
  // phase's geometry asks).
  void Read(void* memory, std::size_t bytes, int phase) override {
    if (phase < 0 || std::size_t(phase) >= phase_slices_.size()) {
      throw InputError(fmt::format("{}: no phase {} in a series of {}", where_, phase, phase_slices_.size()));
    }
    slices_ = &phase_slices_[std::size_t(phase)];
    const std::size_t voxel_bytes = BytesPerVoxel(*VoxelTypeNamed(header_.voxel_type()));
    const std::size_t slices = positions_.empty() ? slices_->size() : grid_slices_;
    if (bytes != slice_voxels_ * voxel_bytes * slices) {
      throw InputError(fmt::format("{}: {} bytes of memory for the series' voxels", where_, bytes));
    }
    if (!positions_.empty()) {
      ReadEven(static_cast<float*>(memory));
    } else {
      for (std::size_t k = 0; k < slices_->size(); ++k) {
        DecodeSlice(k, static_cast<char*>(memory) + k * slice_voxels_ * voxel_bytes);
      }
    }
    if (std::size_t(phase) + 1 == phase_slices_.size()) std::vector<char>().swap(stored_frames_);
  }

 private:
  // A time series: its phases, and their times where the files give them.
  void SetPhases(const dicom::SortedSeries& series) {
    header_.set_phases(std::uint32_t(phase_slices_.size()));
    for (double t : series.phase_seconds) header_.add_phase_seconds(t);
    if (series.phase_seconds.empty()) {
      header_.add_notes(
          fmt::format("a time series of {} phases ordered by {}; its files give no Trigger Times that "
                      "rise phase by phase, so the phases have no times",
                      phase_slices_.size(), series.phase_order));
    }
  }

  // Slice k's voxels into `out`: as stored where the series is rescaled alike
  // and straight, else as float32 (shifted onto the regular grid where tilted).
  void DecodeSlice(std::size_t k, char* out) {
    if ((*slices_)[k].frame >= 0) return DecodeFrame(k, out);
    auto io = itk::GDCMImageIO::New();
    try {
      io->SetFileName((*slices_)[k].file);
      io->ReadImageInformation();
      const std::size_t n = io->GetImageSizeInPixels();
      if (io->GetNumberOfComponents() != 1 || n != slice_voxels_ ||
          (rescaled_alike_ && io->GetComponentType() != type_)) {
        throw InputError(fmt::format("{}: a slice of series {} differs from the first in size or voxel type", where_,
                                     dicom::Describe(series_)));
      }
      itk::ImageIORegion region(io->GetNumberOfDimensions());
      for (unsigned a = 0; a < io->GetNumberOfDimensions(); ++a) {
        region.SetIndex(a, 0);
        region.SetSize(a, io->GetDimensions(a));
      }
      io->SetIORegion(region);
      if (header_.voxel_type() != "float32") {
        io->Read(out);
        return;
      }
      scratch_.resize(io->GetImageSizeInBytes());
      io->Read(scratch_.data());
      ToFloat(io->GetComponentType(), scratch_.data(), reinterpret_cast<float*>(out), n);
      if (!shifts_.empty()) ShiftSlice(reinterpret_cast<float*>(out), shifts_[k], io->GetComponentType());
    } catch (const itk::ExceptionObject& e) {
      throw Failed(e);
    }
  }

  // Slice k, a frame of the multi-frame file, into `out`: as stored where
  // every frame's rescale is the identity, else as float32 rescaled by its
  // own (shifted onto the regular grid where tilted).
  void DecodeFrame(std::size_t k, char* out) {
    const dicom::Slice& frame = (*slices_)[k];
    if (stored_frames_.empty()) DecodeFrames(frame.file);
    const std::size_t stored_bytes = StoredBytes();
    const char* stored = stored_frames_.data() + std::size_t(frame.frame) * slice_voxels_ * stored_bytes;
    if (header_.voxel_type() != "float32") {
      std::memcpy(out, stored, slice_voxels_ * stored_bytes);
      return;
    }
    float* values = reinterpret_cast<float*>(out);
    ToFloat(type_, stored, values, slice_voxels_);
    for (std::size_t i = 0; i < slice_voxels_; ++i) {
      values[i] = float(double(values[i]) * frame.rescale_slope + frame.rescale_intercept);
    }
    if (!shifts_.empty()) ShiftSlice(values, shifts_[k], type_);
  }

  // Every frame of `file`, as stored, into stored_frames_: GDCM decodes a
  // compressed file's frames together.
  void DecodeFrames(const std::string& file) {
    gdcm::ImageReader reader;
    reader.SetFileName(file.c_str());
    if (!reader.Read()) {
      throw InputError(fmt::format("{}: cannot decode the frames of series {}", where_, dicom::Describe(series_)));
    }
    const gdcm::Image& image = reader.GetImage();
    const std::uint64_t frames = image.GetNumberOfDimensions() > 2 ? image.GetDimension(2) : 1;
    const std::uint64_t length = image.GetBufferLength();
    if (image.GetPixelFormat().GetSamplesPerPixel() != 1 || frames != frame_count_ ||
        std::uint64_t(image.GetDimension(0)) * image.GetDimension(1) != slice_voxels_ ||
        length != frame_count_ * slice_voxels_ * StoredBytes()) {
      throw InputError(fmt::format("{}: the frames of series {} decode to {} bytes, not the {} frames of {} "
                                   "voxels of {} its header describes",
                                   where_, dicom::Describe(series_), length, frame_count_, slice_voxels_,
                                   ComponentName(type_)));
    }
    stored_frames_.resize(length);
    if (!image.GetBuffer(stored_frames_.data())) {
      throw InputError(fmt::format("{}: cannot decode the frames of series {}", where_, dicom::Describe(series_)));
    }
  }

  // Bytes of a stored value of type_.
  std::size_t StoredBytes() const {
    using C = itk::IOComponentEnum;
    switch (type_) {
      case C::UCHAR:
      case C::CHAR:
        return 1;
      case C::USHORT:
      case C::SHORT:
        return 2;
      case C::UINT:
      case C::INT:
      case C::FLOAT:
        return 4;
      default:
        return 8;
    }
  }

  // An unevenly spaced series: every slice of the even grid interpolated
  // linearly along the normal between the two slices around it, which are
  // decoded once each, in order (two slices in memory at a time).
  void Even(const dicom::SeriesGeometry& g) {
    for (const dicom::Slice& s : g.slices) positions_.push_back(s.along_normal - g.slices.front().along_normal);
    grid_slices_ = g.GridSlices();
    gap_mm_ = g.slice_gap_mm;
    header_.set_voxel_type("float32");
    header_.add_notes(
        fmt::format("resampled onto an even grid of {:.3g} mm along the slices' normal (the "
                    "series' smallest gap): its gaps run to {:.3g} mm, the largest between {}",
                    g.slice_gap_mm, g.largest_gap_mm, g.largest_gap_between));
  }

  void ReadEven(float* memory) {
    std::vector<float> below(slice_voxels_), above(slice_voxels_);
    std::size_t k = 0;  // the slices decoded: k below, k + 1 above
    DecodeSlice(0, reinterpret_cast<char*>(below.data()));
    DecodeSlice(std::min<std::size_t>(1, slices_->size() - 1), reinterpret_cast<char*>(above.data()));
    for (std::size_t z = 0; z < grid_slices_; ++z) {
      const double at = std::min(double(z) * gap_mm_, positions_.back());
      while (k + 2 < positions_.size() && positions_[k + 1] < at) {
        ++k;
        std::swap(below, above);
        DecodeSlice(k + 1, reinterpret_cast<char*>(above.data()));
      }
      const double span = positions_[k + 1] - positions_[k];
      const float w = float(std::clamp(span > 0 ? (at - positions_[k]) / span : 0.0, 0.0, 1.0));
      float* out = memory + z * slice_voxels_;
      for (std::size_t i = 0; i < slice_voxels_; ++i) out[i] = below[i] + w * (above[i] - below[i]);
    }
  }

  // A gantry-tilted series: each slice's offset in its own plane (voxels along
  // row and column) from where a regular grid puts it; read as float32.
  void Shear(const dicom::SeriesGeometry& g, double row_mm, double col_mm, const std::array<int, 3>& dims) {
    const dicom::Slice& first = g.slices.front();
    for (std::size_t k = 0; k < g.slices.size(); ++k) {
      double d[3];
      for (int a = 0; a < 3; ++a) d[a] = g.slices[k].position[a] - first.position[a];
      shifts_.push_back({dicom::Dot3(d, g.row) / row_mm, dicom::Dot3(d, g.col) / col_mm});
    }
    width_ = dims[0];
    height_ = dims[1];
    header_.set_voxel_type("float32");
    header_.add_notes(
        fmt::format("resampled from a gantry tilt of {:.1f} degrees onto a regular grid: each slice "
                    "shifted in its own plane",
                    g.tilt_deg));
  }

  // Moves a slice by its offset: the regular grid's voxel (i, j) is the
  // slice's (i - dx, j - dy), interpolated bilinearly; what falls outside the
  // slice takes its lowest value (air). Integer data are rounded again.
  void ShiftSlice(float* slice, std::array<double, 2> shift, itk::IOComponentEnum type) const {
    const std::vector<float> in(slice, slice + std::size_t(width_) * height_);
    const float fill = *std::min_element(in.begin(), in.end());
    const bool integral = type != itk::IOComponentEnum::FLOAT && type != itk::IOComponentEnum::DOUBLE;
    for (int j = 0; j < height_; ++j) {
      for (int i = 0; i < width_; ++i) {
        const double x = i - shift[0], y = j - shift[1];
        const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        auto at = [&](int xi, int yi) {
          return xi < 0 || yi < 0 || xi >= width_ || yi >= height_ ? double(fill)
                                                                   : double(in[std::size_t(yi) * width_ + xi]);
        };
        const double v = (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) +
                         (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
        slice[std::size_t(j) * width_ + i] = float(integral ? std::nearbyint(v) : v);
      }
    }
  }

  InputError Failed(const itk::ExceptionObject& e) const {
    return InputError(
        fmt::format("{}: cannot decode series {}: {}", where_, dicom::Describe(series_), ItkMessage(e, {}, where_)));
  }

  std::string where_;
  reader::Series series_;
  std::vector<std::vector<dicom::Slice>> phase_slices_;  // each phase's slices, sorted along the normal
  const std::vector<dicom::Slice>* slices_ = nullptr;    // the phase being read's
  itk::IOComponentEnum type_ = itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
  bool rescaled_alike_ = true;
  std::size_t slice_voxels_ = 0;
  std::vector<std::array<double, 2>> shifts_;  // per slice, for a tilted series; empty otherwise
  int width_ = 0, height_ = 0;
  std::vector<double> positions_;  // per slice, mm along the normal from the first, for an uneven series; else empty
  std::size_t grid_slices_ = 0;    // the even grid's slices, for an uneven series
  double gap_mm_ = 0;
  std::vector<char> scratch_;  // a slice as stored, on its way to float32
  // A multi-frame file: its frames, and every frame's stored values from the
  // first read to the last phase's.
  std::size_t frame_count_ = 0;
  std::vector<char> stored_frames_;
};

}  // namespace

namespace reader {

std::unique_ptr<VolumeRead> OpenVolumeFile(const fs::path& path, const std::vector<fs::path>& named,
                                           const ReadOptions& options) {
  const std::string& shown = options.shown;
  itk_adapter::InitToolkits();
  // The files the header names sit beside it when it names them so; any
  // other way (a subfolder, an absolute path, a list) gets a rewrite of the
  // header that names where the cage placed them.
  if (nrrd::IsGzipped(path)) {
    const fs::path read = WriteScratch(nrrd::GzippedRewrite(path, shown), options);
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
    const std::string rewritten = nrrd::HasMagic(path, shown) ? nrrd::RewrittenHeader(path, named, false, shown)
                                                              : metaimage::RewrittenHeader(path, named, shown);
    read = WriteScratch(rewritten, options);
  }
  std::vector<fs::path> placed = named;
  for (const fs::path& f : refs.files) {
    if (beside) placed.push_back(f);
  }
  try {
    try {
      return OpenWithItk(read, placed, options);
    } catch (const itk::ExceptionObject& e) {
      if (!nrrd::IsSpaceWithSpacingsError(e.GetDescription())) throw;
      read = WriteScratch(nrrd::RewrittenHeader(path, beside ? refs.files : named, true, shown), options);
      return OpenWithItk(read, placed, options);
    }
  } catch (const itk::ExceptionObject& e) {
    throw InputError(fmt::format("{}: {}", shown, ItkMessage(e, {path, read}, shown)));
  }
}

std::unique_ptr<VolumeRead> OpenDicomSeries(const std::vector<DicomFile>& files, const std::string& series_uid,
                                            const ReadOptions& options) {
  itk_adapter::InitToolkits();
  return std::make_unique<DicomSeriesRead>(dicom::ChooseSeries(files, series_uid, options), options.max_voxels);
}

SeriesList ListDicomSeries(const std::vector<DicomFile>& files, const ReadOptions& options) {
  itk_adapter::InitToolkits();
  return dicom::ListSeries(files, options);
}

}  // namespace reader
}  // namespace cinevol

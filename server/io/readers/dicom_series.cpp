// DICOM series through GDCM: the series chosen, sorted and checked by
// io/formats/dicom/, the pixels decoded slice by slice (JPEG 2000 and other
// compressed transfer syntaxes included; rescale slope and intercept applied).
#include <itkGDCMImageIO.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"
#include "core/volume.h"
#include "core/voxel_memory.h"
#include "io/formats/dicom/series.h"
#include "io/readers/formats.h"
#include "io/readers/itk_image.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

using itk_image::ComponentName;
using itk_image::ItkMessage;
using itk_image::SetGeometry;
using itk_image::VoxelTypeOf;

// Converts `n` values of ITK component `from` at `in` to float32 at `out`.
void ToFloat(itk::IOComponentEnum from, const void* in, float* out, std::size_t n) {
  using C = itk::IOComponentEnum;
  auto copy = [&](auto* typed) {
    for (std::size_t i = 0; i < n; ++i) out[i] = float(typed[i]);
  };
  switch (from) {
    case C::UCHAR: copy(static_cast<const std::uint8_t*>(in)); break;
    case C::CHAR: copy(static_cast<const std::int8_t*>(in)); break;
    case C::USHORT: copy(static_cast<const std::uint16_t*>(in)); break;
    case C::SHORT: copy(static_cast<const std::int16_t*>(in)); break;
    case C::UINT: copy(static_cast<const std::uint32_t*>(in)); break;
    case C::INT: copy(static_cast<const std::int32_t*>(in)); break;
    case C::FLOAT: copy(static_cast<const float*>(in)); break;
    case C::DOUBLE: copy(static_cast<const double*>(in)); break;
    default: throw InputError("a slice of a voxel type cinevol does not read");
  }
}

// One series, its slices sorted and its header known; the pixels are
// decoded slice by slice (GDCM: JPEG 2000 and other compressed transfer
// syntaxes included; rescale slope and intercept applied).
class DicomSeriesRead final : public reader::VolumeRead {
 public:
  DicomSeriesRead(const formats::dicom::SortedSeries& series, std::uint64_t max_voxels)
      : where_(series.shown), series_(series.info) {
    const formats::dicom::SeriesGeometry& g = series.geometry;
    for (const formats::dicom::Slice& s : g.slices) files_.push_back(s.file);
    auto io = itk::GDCMImageIO::New();
    try {
      // Header sizes are checked before decoding: absurd rows/columns never allocate.
      io->SetFileName(files_[0]);
      io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
      throw Failed(e);
    }
    if (io->GetNumberOfComponents() != 1) {
      throw InputError(fmt::format("{}: series {} holds pixels of {} components; cinevol reads grey-scale series",
                                   where_, formats::dicom::Describe(series_), io->GetNumberOfComponents()));
    }
    const std::uint64_t frames = io->GetNumberOfDimensions() > 2 ? std::max<std::uint64_t>(1, io->GetDimensions(2)) : 1;
    if (frames > 1 && files_.size() > 1) {
      throw InputError(fmt::format("{}: series {} has multi-frame files; cinevol reads one such file, or single-frame "
                                   "slices", where_, formats::dicom::Describe(series_)));
    }
    const std::array<int, 3> dims{int(std::min<std::uint64_t>(io->GetDimensions(0), 1u << 30)),
                                  int(std::min<std::uint64_t>(io->GetDimensions(1), 1u << 30)),
                                  int(std::min<std::uint64_t>(files_.size() * frames, 1u << 30))};
    CheckVolumeGeometry({dims[0], dims[1], dims[2]},
                        {float(io->GetSpacing(0)), float(io->GetSpacing(1)), float(g.slice_gap_mm)}, where_);
    const std::uint64_t voxels = std::uint64_t(dims[0]) * std::uint64_t(dims[1]) * std::uint64_t(dims[2]);
    if (voxels > max_voxels) {
      throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds this server's limit of {} voxels", where_,
                                   dims[0], dims[1], dims[2], voxels, max_voxels));
    }
    // Geometry from the sorted positions, not from the first two files.
    std::array<double, 9> direction;
    for (int r = 0; r < 3; ++r) {
      direction[3 * r + 0] = g.row[r];
      direction[3 * r + 1] = g.col[r];
      direction[3 * r + 2] = g.normal[r];
    }
    const formats::dicom::Slice& first = g.slices.front();
    SetGeometry(header_, dims, {io->GetSpacing(0), io->GetSpacing(1), g.slice_gap_mm},
                           {first.position[0], first.position[1], first.position[2]}, direction);
    type_ = io->GetComponentType();
    rescaled_alike_ = series.rescaled_alike;
    header_.set_voxel_type(rescaled_alike_ ? VoxelTypeOf(type_) : "float32");
    if (header_.voxel_type().empty()) {
      throw InputError(fmt::format("{}: series {} holds voxels of type {}, which cinevol does not read", where_,
                                   formats::dicom::Describe(series_), ComponentName(type_)));
    }
    header_.set_modality(series.modality);
    header_.set_value_unit(header_.modality() == "CT" ? "HU" : "");
    std::string original = ComponentName(io->GetInternalComponentType());
    if (io->GetRescaleSlope() != 1.0 || io->GetRescaleIntercept() != 0.0) {
      original += fmt::format(" (rescale slope {:g}, intercept {:g})", io->GetRescaleSlope(), io->GetRescaleIntercept());
    }
    header_.set_original_type(original);
    slice_voxels_ = std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(frames);
    if (g.tilt_deg > formats::dicom::kMaxTiltDeg) Shear(g, io->GetSpacing(0), io->GetSpacing(1), dims);
  }

  void Read(void* memory, std::size_t bytes) override {
    const std::size_t voxel_bytes = BytesPerVoxel(*VoxelTypeNamed(header_.voxel_type()));
    if (bytes != slice_voxels_ * voxel_bytes * files_.size()) {
      throw InputError(fmt::format("{}: {} bytes of memory for the series' voxels", where_, bytes));
    }
    std::vector<char> scratch;
    for (std::size_t k = 0; k < files_.size(); ++k) {
      auto io = itk::GDCMImageIO::New();
      char* out = static_cast<char*>(memory) + k * slice_voxels_ * voxel_bytes;
      try {
        io->SetFileName(files_[k]);
        io->ReadImageInformation();
        const std::size_t n = io->GetImageSizeInPixels();
        if (io->GetNumberOfComponents() != 1 || n != slice_voxels_ ||
            (rescaled_alike_ && io->GetComponentType() != type_)) {
          throw InputError(fmt::format("{}: a slice of series {} differs from the first in size or voxel type",
                                       where_, formats::dicom::Describe(series_)));
        }
        itk::ImageIORegion region(io->GetNumberOfDimensions());
        for (unsigned a = 0; a < io->GetNumberOfDimensions(); ++a) {
          region.SetIndex(a, 0);
          region.SetSize(a, io->GetDimensions(a));
        }
        io->SetIORegion(region);
        if (rescaled_alike_ && shifts_.empty()) {
          io->Read(out);
        } else {
          scratch.resize(io->GetImageSizeInBytes());
          io->Read(scratch.data());
          ToFloat(io->GetComponentType(), scratch.data(), reinterpret_cast<float*>(out), n);
          if (!shifts_.empty()) ShiftSlice(reinterpret_cast<float*>(out), shifts_[k], io->GetComponentType());
        }
      } catch (const itk::ExceptionObject& e) {
        throw Failed(e);
      }
    }
  }

 private:
  // A gantry-tilted series: each slice's offset in its own plane (voxels along
  // row and column) from where a regular grid puts it; read as float32.
  void Shear(const formats::dicom::SeriesGeometry& g, double row_mm, double col_mm,
             const std::array<int, 3>& dims) {
    const formats::dicom::Slice& first = g.slices.front();
    for (std::size_t k = 0; k < g.slices.size(); ++k) {
      double d[3];
      for (int a = 0; a < 3; ++a) d[a] = g.slices[k].position[a] - first.position[a];
      shifts_.push_back({formats::dicom::Dot3(d, g.row) / row_mm, formats::dicom::Dot3(d, g.col) / col_mm});
    }
    width_ = dims[0];
    height_ = dims[1];
    header_.set_voxel_type("float32");
    header_.add_notes(fmt::format("resampled from a gantry tilt of {:.1f} degrees onto a regular grid: each slice "
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
    return InputError(fmt::format("{}: cannot decode series {}: {}", where_, formats::dicom::Describe(series_),
                                  ItkMessage(e, {}, where_)));
  }

  std::string where_;
  reader::Series series_;
  std::vector<std::string> files_;  // sorted along the normal
  itk::IOComponentEnum type_ = itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
  bool rescaled_alike_ = true;
  std::size_t slice_voxels_ = 0;
  std::vector<std::array<double, 2>> shifts_;  // per slice, for a tilted series; empty otherwise
  int width_ = 0, height_ = 0;
};

}  // namespace

namespace reader {

std::unique_ptr<VolumeRead> OpenDicomSeries(const std::vector<DicomFile>& files, const std::string& series_uid,
                                            const ReadOptions& options) {
  itk_image::InitToolkits();
  return std::make_unique<DicomSeriesRead>(formats::dicom::ChooseSeries(files, series_uid, options),
                                           options.max_voxels);
}

SeriesList ListDicomSeries(const std::vector<DicomFile>& files, const ReadOptions& options) {
  itk_image::InitToolkits();
  return formats::dicom::ListSeries(files, options);
}


}  // namespace reader
}  // namespace cinevol

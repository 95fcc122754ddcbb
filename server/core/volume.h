// A scalar volume in host memory: voxel values in physical units (HU for CT),
// its grid, spacing and patient orientation.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/value_histogram.h"
#include "core/vec.h"
#include "core/voxel_memory.h"

namespace cinevol {

// Limits that reject absurd headers before any memory is touched.
inline constexpr int kMaxVoxelsPerAxis = 8192;
inline constexpr std::size_t kMaxVoxels = std::size_t{1} << 30;  // 2 GiB as 16-bit
// Voxel spacing, mm: from 0.1 um (beyond any micro-CT) to 10 m. Below the
// lower bound every millimetre-to-voxel conversion (a table search's radius,
// a slab's samples, a ray's steps) becomes a count no integer holds.
inline constexpr float kMinSpacingMm = 1e-4f;
inline constexpr float kMaxSpacingMm = 1e4f;
// Voxel values are held within +-kMaxVoxelMagnitude: float32 reaches 3.4e38,
// but a transfer function's table and the quantisation to 16 bits subtract
// and scale values, and need the headroom to stay finite.
inline constexpr float kMaxVoxelMagnitude = 1e30f;

// How voxel values are held. Integer data within a span of 65535 (all CT in
// HU, 8/12/16-bit MR) is stored as 16-bit with an offset; anything else as float.
enum class VoxelStorage { kUInt16, kFloat32 };

const char* ToString(VoxelStorage storage);

// DICOM Window Center (0028,1050) and Window Width (0028,1051), in the
// volume's value unit (reading/window_level.h applies it).
struct VoiWindow {
  double center = 50;  // level; the default is soft tissue's
  double width = 350;  // >= 1, as DICOM requires
};

// DICOM fields naming who and what a volume shows, for the corners of its
// reading views: answered to the people who may render it, never logged.
struct PatientIdentity {
  std::string patient_name;  // as stored: "FAMILY^GIVEN"
  std::string patient_id;
  std::string study_date;  // YYYYMMDD
  std::string study_description;
  std::string series_description;
};

// What a volume is and where it came from; carried along, never rendered.
struct VolumeMetadata {
  std::string source;         // the file, folder or phantom it came from
  std::string modality;       // "CT", "MR", ... or "" when the file does not say
  std::string value_unit;     // "HU" for CT in Hounsfield units, else ""
  std::string original_type;  // the file's voxel type, e.g. "int16", "uint8 * 2.2086"
  // LPS position (mm) of the centre of voxel (0,0,0), and the LPS direction of
  // each index axis: direction[3*r + c] is row r of the 3x3 matrix whose
  // column c is index axis c.
  std::array<double, 3> origin_mm{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::size_t non_finite_replaced = 0;     // NaN/Inf voxels sanitised on load
  std::size_t subnormals_flushed = 0;      // values below float's normal range, made 0
  std::string orientation_override;        // the code a load gave instead of the file's direction, e.g. "LPI"
  std::vector<std::string> notes;          // what loading changed: a resampling, a mirroring
  PatientIdentity identity;                // empty unless it came from DICOM
  std::optional<VoiWindow> stored_window;  // the window its DICOM gives, if any
  // DICOM's Frame of Reference UID (0020,0052): the patient space its
  // positions are in; empty where the file names none (NIfTI, NRRD, ...).
  std::string frame_of_reference_uid;
  // A PET's SUVbw per value (value * suv_factor = SUVbw; io/suv.h), 0 where
  // it has none; suv_refused says why for a PET without (empty otherwise).
  double suv_factor = 0;
  std::string suv_refused;
};

// The patient direction each index axis points to most, as three letters
// from L/R, P/A and S/I: "LPS" (the DICOM convention), "RAS", ...
std::string OrientationCode(const std::array<double, 9>& direction);
// The direction matrix of such a code; nullopt unless it is three letters,
// one from each pair (case-insensitive).
std::optional<std::array<double, 9>> DirectionOfCode(std::string_view code);

class Volume {
 public:
  // Takes `voxels`, one `type` value per voxel (x fastest), and chooses the
  // storage, converting within that memory where the storage is no wider.
  // Sanitises on the way: NaN and -Inf become the smallest finite value and
  // +Inf the largest (metadata.non_finite_replaced), subnormals 0
  // (metadata.subnormals_flushed). Throws InputError naming metadata.source
  // for bad dims or spacing, a block of the wrong size, or values beyond
  // +-kMaxVoxelMagnitude.
  Volume(Vec3i dims, Vec3f spacing_mm, VoxelType type, MemoryBlock voxels, VolumeMetadata metadata);
  // The same from float values (phantoms, tests).
  Volume(Vec3i dims, Vec3f spacing_mm, std::vector<float> values, VolumeMetadata metadata);

  // Takes `direction` for the index axes' patient directions instead of the
  // file's (`code` names it: an override for files without an orientation,
  // or a wrong one); the origin stays where voxel (0,0,0) is.
  void Reorient(const std::array<double, 9>& direction, const std::string& code);
  // Takes the values as being in `unit` (a file that did not say: "HU" for a
  // CT its values show to be in HU), with a note saying why.
  void SetValueUnit(std::string unit, std::string why);

  Vec3i dims() const { return dims_; }
  Vec3f spacing_mm() const { return spacing_mm_; }
  Vec3f extent_mm() const { return ToFloat(dims_) * spacing_mm_; }
  std::size_t voxel_count() const;
  VoxelStorage storage() const { return storage_; }
  const VolumeMetadata& metadata() const { return metadata_; }
  float min_value() const { return min_value_; }
  float max_value() const { return max_value_; }

  // 16-bit storage: value = stored + stored_offset(). The other is empty.
  ValuesView<std::uint16_t> u16() const;
  ValuesView<float> f32() const;
  float stored_offset() const { return stored_offset_; }

  float Value(int x, int y, int z) const;
  float ValueAtIndex(std::size_t i) const;
  // Host memory held: the voxels, their block ranges and the histogram.
  std::size_t MemoryBytes() const;
  // What a volume of `voxels` voxels read as `type` may hold at most while it
  // is made and afterwards (the reader's block, a wider storage, the block
  // ranges): what a load reserves before any voxel is read.
  static std::uint64_t BytesToLoad(VoxelType type, std::uint64_t voxels);

  const ValueHistogram& histogram() const { return histogram_; }

  // The value range of each block of kBlockSize^3 voxels (x fastest), so
  // finding what a transfer function shows need not visit every voxel.
  struct ValueRange {
    float lo, hi;
  };
  static constexpr int kBlockSize = 4;
  Vec3i block_counts() const;
  const std::vector<ValueRange>& block_ranges() const { return block_ranges_; }

 private:
  // Sanitises and stores `voxels`, values of type T.
  template <class T>
  void Store(MemoryBlock voxels);
  // Volumes are held with right-handed index axes, as the renderer's world
  // (index space in mm) is: one whose direction has a negative determinant
  // (NIfTI stored LAS, an override such as LPI) is mirrored along x, its
  // direction and origin adjusted, so the patient is not shown mirrored.
  void MakeRightHanded();
  void SummariseValues();  // the histogram and block ranges

  Vec3i dims_;
  Vec3f spacing_mm_;
  VoxelStorage storage_ = VoxelStorage::kFloat32;
  MemoryBlock voxels_;  // uint16 or float32, per storage_
  float stored_offset_ = 0.0f;
  float min_value_ = 0.0f;
  float max_value_ = 0.0f;
  ValueHistogram histogram_;
  std::vector<ValueRange> block_ranges_;
  VolumeMetadata metadata_;
};

// A time series (4D: cardiac phases, breathing phases, a dynamic series):
// its phases, alike in grid, voxel type and placement, and each one's time
// from the first in seconds (empty where the input does not say). A still
// volume is a series of one phase. At most kMaxPhases phases.
struct VolumeSeries {
  std::vector<Volume> phases;
  std::vector<double> seconds;
};
inline constexpr int kMaxPhases = 4096;

// Throws InputError naming `what` when dims or spacing are outside the limits.
void CheckVolumeGeometry(Vec3i dims, Vec3f spacing_mm, const std::string& what);

// Throws InputError naming `what` when `phases` volumes of `dims` hold more
// voxels than a server's `max_voxels` (its --max-voxels): every phase
// counted, before any voxel is read.
void CheckVoxelLimit(Vec3i dims, std::uint64_t phases, std::uint64_t max_voxels, const std::string& what);

}  // namespace cinevol

// Volume: storage choice, sanitising and geometry checks.
#include "core/volume.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "core/error.h"
#include "core/parallel_for.h"

namespace cinevol {

const char* ToString(VoxelStorage storage) {
  return storage == VoxelStorage::kUInt16 ? "uint16" : "float32";
}

void CheckVolumeGeometry(Vec3i dims, Vec3f spacing_mm, const std::string& what) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1 || dims[a] > kMaxVoxelsPerAxis) {
      throw InputError(fmt::format("{}: dimension {} is {}, outside [1, {}]", what, "xyz"[a],
                                   dims[a], kMaxVoxelsPerAxis));
    }
    if (!(spacing_mm[a] > 0.0f) || !std::isfinite(spacing_mm[a]) || spacing_mm[a] > 1e4f) {
      throw InputError(fmt::format("{}: spacing {} is {} mm, outside (0, 1e4]", what, "xyz"[a],
                                   spacing_mm[a]));
    }
  }
  const std::size_t count = std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z);
  if (count > kMaxVoxels) {
    throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds the limit of {}", what, dims.x,
                                 dims.y, dims.z, count, kMaxVoxels));
  }
}

namespace {

// Replaces non-finite values in place; returns how many and the finite range.
std::size_t SanitiseNonFinite(std::vector<float>& values, float& lo, float& hi) {
  lo = std::numeric_limits<float>::max();
  hi = std::numeric_limits<float>::lowest();
  std::size_t bad = 0;
  for (float v : values) {
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    } else {
      ++bad;
    }
  }
  if (lo > hi) lo = hi = 0.0f;  // nothing finite at all
  if (bad > 0) {
    for (float& v : values) {
      if (std::isnan(v) || v == -std::numeric_limits<float>::infinity()) v = lo;
      if (v == std::numeric_limits<float>::infinity()) v = hi;
    }
  }
  return bad;
}

std::vector<Volume::ValueRange> BlockRanges(const std::vector<float>& values, Vec3i dims, Vec3i blocks) {
  std::vector<Volume::ValueRange> ranges(std::size_t(blocks.x) * blocks.y * blocks.z,
                                         {std::numeric_limits<float>::max(), std::numeric_limits<float>::lowest()});
  const int b = Volume::kBlockSize;
  ParallelFor(blocks.z, [&](std::int64_t bz) {  // one slab of blocks per task
    for (int z = int(bz) * b; z < std::min(dims.z, int(bz + 1) * b); ++z) {
      for (int y = 0; y < dims.y; ++y) {
        const float* row = values.data() + (std::size_t(z) * dims.y + y) * dims.x;
        Volume::ValueRange* out = ranges.data() + (std::size_t(bz) * blocks.y + y / b) * blocks.x;
        for (int x = 0; x < dims.x; ++x) {
          out[x / b].lo = std::min(out[x / b].lo, row[x]);
          out[x / b].hi = std::max(out[x / b].hi, row[x]);
        }
      }
    }
  });
  return ranges;
}

bool AllIntegers(const std::vector<float>& values) {
  return std::all_of(values.begin(), values.end(), [](float v) { return v == std::nearbyint(v); });
}

}  // namespace

Volume::Volume(Vec3i dims, Vec3f spacing_mm, std::vector<float> values, VolumeMetadata metadata)
    : dims_(dims), spacing_mm_(spacing_mm), metadata_(std::move(metadata)) {
  CheckVolumeGeometry(dims, spacing_mm, metadata_.source);
  if (values.size() != voxel_count()) {
    throw InputError(fmt::format("{}: {} voxel values for a {}x{}x{} grid", metadata_.source,
                                 values.size(), dims.x, dims.y, dims.z));
  }
  metadata_.non_finite_replaced = SanitiseNonFinite(values, min_value_, max_value_);
  histogram_ = ValueHistogram::Of(values, min_value_, max_value_);
  block_ranges_ = BlockRanges(values, dims_, block_counts());

  const bool fits_u16 = double(max_value_) - double(min_value_) <= 65535.0;
  if (fits_u16 && AllIntegers(values)) {
    storage_ = VoxelStorage::kUInt16;
    stored_offset_ = min_value_;
    u16_.resize(values.size());
    std::transform(values.begin(), values.end(), u16_.begin(), [this](float v) {
      return static_cast<std::uint16_t>(v - stored_offset_);
    });
  } else {
    storage_ = VoxelStorage::kFloat32;
    f32_ = std::move(values);
  }
}

Vec3i Volume::block_counts() const {
  return {(dims_.x + kBlockSize - 1) / kBlockSize, (dims_.y + kBlockSize - 1) / kBlockSize,
          (dims_.z + kBlockSize - 1) / kBlockSize};
}

std::size_t Volume::voxel_count() const {
  return std::size_t(dims_.x) * std::size_t(dims_.y) * std::size_t(dims_.z);
}

float Volume::ValueAtIndex(std::size_t i) const {
  return storage_ == VoxelStorage::kUInt16 ? u16_[i] + stored_offset_ : f32_[i];
}

float Volume::Value(int x, int y, int z) const {
  return ValueAtIndex((std::size_t(z) * dims_.y + y) * dims_.x + x);
}

std::size_t Volume::MemoryBytes() const {
  return u16_.size() * sizeof(std::uint16_t) + f32_.size() * sizeof(float);
}

}  // namespace cinevol

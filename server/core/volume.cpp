// Volume: storage choice, sanitising and geometry checks.
#include "core/volume.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <type_traits>

#include "core/blocks.h"
#include "core/error.h"
#include "core/parallel_for.h"

namespace cinevol {

const char* ToString(VoxelStorage storage) { return storage == VoxelStorage::kUInt16 ? "uint16" : "float32"; }

void CheckVolumeGeometry(Vec3i dims, Vec3f spacing_mm, const std::string& what) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1 || dims[a] > kMaxVoxelsPerAxis) {
      throw InputError(
          fmt::format("{}: dimension {} is {}, outside [1, {}]", what, "xyz"[a], dims[a], kMaxVoxelsPerAxis));
    }
    if (!(spacing_mm[a] >= kMinSpacingMm && spacing_mm[a] <= kMaxSpacingMm)) {  // NaN too
      throw InputError(fmt::format("{}: spacing {} is {:g} mm, outside [{:g}, {:g}]", what, "xyz"[a], spacing_mm[a],
                                   kMinSpacingMm, kMaxSpacingMm));
    }
  }
  const std::size_t count = std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z);
  if (count > kMaxVoxels) {
    throw InputError(fmt::format("{}: {}x{}x{} = {} voxels exceeds the limit of {}", what, dims.x, dims.y, dims.z,
                                 count, kMaxVoxels));
  }
}

void CheckVoxelLimit(Vec3i dims, std::uint64_t phases, std::uint64_t max_voxels, const std::string& what) {
  const std::uint64_t voxels = std::uint64_t(dims.x) * std::uint64_t(dims.y) * std::uint64_t(dims.z);
  if (voxels * phases <= max_voxels) return;
  throw InputError(fmt::format("{}: {}x{}x{}{} = {} voxels exceeds this server's limit of {} voxels", what, dims.x,
                               dims.y, dims.z, phases > 1 ? fmt::format(" voxels x {} phases", phases) : "",
                               voxels * phases, max_voxels));
}

namespace {

constexpr std::int64_t kChunk = std::int64_t{1} << 20;  // voxels per parallel task

// What a first pass over a reader's values finds; values are taken as
// sanitising will leave them (subnormals as 0, non-finite ones aside).
struct ValueScan {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  std::size_t non_finite = 0, subnormal = 0;
  bool integral = true;  // every finite value is an integer
  double beyond = 0;     // a value past kMaxVoxelMagnitude (0: none)

  void Merge(const ValueScan& o) {
    lo = std::min(lo, o.lo);
    hi = std::max(hi, o.hi);
    non_finite += o.non_finite;
    subnormal += o.subnormal;
    integral = integral && o.integral;
    if (beyond == 0) beyond = o.beyond;
  }
};

template <class T>
ValueScan Scan(const T* values, std::size_t n) {
  std::vector<ValueScan> parts(std::size_t((std::int64_t(n) + kChunk - 1) / kChunk));
  ParallelFor(std::int64_t(parts.size()), [&](std::int64_t part) {
    ValueScan s;
    const std::size_t end = std::min(n, std::size_t(part + 1) * std::size_t(kChunk));
    for (std::size_t i = std::size_t(part) * std::size_t(kChunk); i < end; ++i) {
      double v = double(values[i]);
      if constexpr (std::is_floating_point_v<T>) {
        if (!std::isfinite(v)) {
          ++s.non_finite;
          continue;
        }
        if (v != 0 && std::fabs(v) < double(std::numeric_limits<float>::min())) {
          ++s.subnormal;
          v = 0;
        }
        if (s.integral && v != std::nearbyint(v)) s.integral = false;
      }
      if (std::fabs(v) > double(kMaxVoxelMagnitude) && s.beyond == 0) s.beyond = v;
      s.lo = std::min(s.lo, v);
      s.hi = std::max(s.hi, v);
    }
    parts[std::size_t(part)] = s;
  });
  ValueScan all;
  for (const ValueScan& p : parts) all.Merge(p);
  if (all.lo > all.hi) all.lo = all.hi = 0;  // nothing finite at all
  return all;
}

// The value sanitising leaves in place of `v`: non-finite ones clamped to the
// finite range, subnormals 0.
template <class T>
float Sanitised(T v, float lo, float hi) {
  if constexpr (std::is_floating_point_v<T>) {
    if (std::isnan(v)) return lo;
    if (std::isinf(v)) return v > 0 ? hi : lo;
    if (v != 0 && std::fabs(double(v)) < double(std::numeric_limits<float>::min())) return 0.0f;
  }
  return float(v);
}

// Writes out[i] = f(in[i]) for every voxel. Where `Out` is narrower than
// `In` in the same memory, in order (each output lands at or before the
// input it replaces); otherwise in parallel.
template <class In, class Out, class F>
void Convert(const In* in, Out* out, std::size_t n, F f) {
  const bool overlapping = static_cast<const void*>(in) == static_cast<const void*>(out);
  if (overlapping && sizeof(Out) < sizeof(In)) {
    for (std::size_t i = 0; i < n; ++i) out[i] = f(in[i]);
    return;
  }
  ParallelFor(std::int64_t((std::int64_t(n) + kChunk - 1) / kChunk), [&](std::int64_t part) {
    const std::size_t end = std::min(n, std::size_t(part + 1) * std::size_t(kChunk));
    for (std::size_t i = std::size_t(part) * std::size_t(kChunk); i < end; ++i) out[i] = f(in[i]);
  });
}

template <class Out>
std::size_t StorageBytes(std::size_t n) {
  return n * sizeof(Out);
}

// Converts `block` (values of type In) into `Out` storage: in the same
// memory when Out is no wider, else into a new block.
template <class In, class Out, class F>
MemoryBlock ConvertBlock(MemoryBlock block, std::size_t n, F f) {
  const In* in = static_cast<const In*>(block.data());
  if (sizeof(Out) <= sizeof(In)) {
    Convert(in, static_cast<Out*>(block.data()), n, f);
    block.Shrink(StorageBytes<Out>(n));
    return block;
  }
  MemoryBlock wider = MemoryBlock::Allocate(StorageBytes<Out>(n));
  Convert(in, static_cast<Out*>(wider.data()), n, f);
  return wider;
}

template <class V>
std::vector<Volume::ValueRange> BlockRanges(const V* values, float offset, Vec3i dims) {
  const Vec3i size{Volume::kBlockSize, Volume::kBlockSize, Volume::kBlockSize};
  std::vector<Volume::ValueRange> ranges(BlockTotal(BlockCounts(dims, size)));
  ForEachBlock(dims, size, 0, [&](std::size_t i, Vec3i lo, Vec3i hi) {
    V mn = values[(std::size_t(lo.z) * dims.y + lo.y) * dims.x + lo.x], mx = mn;
    ForEachVoxel(values, dims, lo, hi, [&](V v) {
      mn = std::min(mn, v);
      mx = std::max(mx, v);
    });
    ranges[i] = {float(mn) + offset, float(mx) + offset};
  });
  return ranges;
}

MemoryBlock FloatBlock(std::vector<float> values) {
  auto* owned = new std::vector<float>(std::move(values));
  return {owned->data(), owned->size() * sizeof(float), MemoryBlock::Pages::kHeap,
          [owned](void*, std::size_t) { delete owned; }};
}

}  // namespace

Volume::Volume(Vec3i dims, Vec3f spacing_mm, std::vector<float> values, VolumeMetadata metadata)
    : Volume(dims, spacing_mm, VoxelType::kFloat32, FloatBlock(std::move(values)), std::move(metadata)) {}

Volume::Volume(Vec3i dims, Vec3f spacing_mm, VoxelType type, MemoryBlock voxels, VolumeMetadata metadata)
    : dims_(dims), spacing_mm_(spacing_mm), metadata_(std::move(metadata)) {
  CheckVolumeGeometry(dims, spacing_mm, metadata_.source);
  const std::size_t n = voxel_count();
  if (voxels.bytes() != n * BytesPerVoxel(type)) {
    throw InputError(fmt::format("{}: {} bytes of {} voxels for a {}x{}x{} grid", metadata_.source, voxels.bytes(),
                                 ToString(type), dims.x, dims.y, dims.z));
  }
  switch (type) {
    case VoxelType::kUInt8:
      Store<std::uint8_t>(std::move(voxels));
      break;
    case VoxelType::kInt8:
      Store<std::int8_t>(std::move(voxels));
      break;
    case VoxelType::kUInt16:
      Store<std::uint16_t>(std::move(voxels));
      break;
    case VoxelType::kInt16:
      Store<std::int16_t>(std::move(voxels));
      break;
    case VoxelType::kUInt32:
      Store<std::uint32_t>(std::move(voxels));
      break;
    case VoxelType::kInt32:
      Store<std::int32_t>(std::move(voxels));
      break;
    case VoxelType::kUInt64:
      Store<std::uint64_t>(std::move(voxels));
      break;
    case VoxelType::kInt64:
      Store<std::int64_t>(std::move(voxels));
      break;
    case VoxelType::kFloat32:
      Store<float>(std::move(voxels));
      break;
    case VoxelType::kFloat64:
      Store<double>(std::move(voxels));
      break;
  }
  MakeRightHanded();
  SummariseValues();
}

void Volume::SummariseValues() {
  if (storage_ == VoxelStorage::kUInt16) {
    histogram_ = ValueHistogram::Of(u16(), stored_offset_, min_value_, max_value_);
    block_ranges_ = BlockRanges(u16().data(), stored_offset_, dims_);
  } else {
    histogram_ = ValueHistogram::Of(f32(), 0.0f, min_value_, max_value_);
    block_ranges_ = BlockRanges(f32().data(), 0.0f, dims_);
  }
}

void Volume::SetValueUnit(std::string unit, std::string why) {
  metadata_.value_unit = std::move(unit);
  metadata_.notes.push_back(std::move(why));
}

void Volume::Reorient(const std::array<double, 9>& direction, const std::string& code) {
  metadata_.notes.push_back(
      fmt::format("orientation {} given at load, the file's being {}", code, OrientationCode(metadata_.direction)));
  metadata_.direction = direction;
  metadata_.orientation_override = code;
  MakeRightHanded();
  SummariseValues();
}

namespace {

double Determinant(const std::array<double, 9>& d) {
  return d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) + d[2] * (d[3] * d[7] - d[4] * d[6]);
}

template <class V>
void MirrorRows(V* voxels, Vec3i dims) {
  ParallelFor(
      std::int64_t(dims.z) * dims.y,
      [&](std::int64_t row) {
        V* begin = voxels + std::size_t(row) * dims.x;
        std::reverse(begin, begin + dims.x);
      },
      0, 64);
}

}  // namespace

void Volume::MakeRightHanded() {
  auto& d = metadata_.direction;
  if (!(Determinant(d) < 0)) return;
  if (storage_ == VoxelStorage::kUInt16) {
    MirrorRows(static_cast<std::uint16_t*>(voxels_.data()), dims_);
  } else {
    MirrorRows(static_cast<float*>(voxels_.data()), dims_);
  }
  const std::string before = OrientationCode(d);
  // Voxel (0,0,0) is now the old (nx-1,0,0); index axis x points the other way.
  const double reach = double(dims_.x - 1) * spacing_mm_.x;
  for (int r = 0; r < 3; ++r) {
    metadata_.origin_mm[r] += d[3 * r] * reach;
    d[3 * r] = -d[3 * r];
  }
  metadata_.notes.push_back(
      fmt::format("held mirrored along x, from {} to {}: its index axes were left-handed, "
                  "the patient is the same",
                  before, OrientationCode(d)));
}

std::string OrientationCode(const std::array<double, 9>& direction) {
  std::string code;
  for (int c = 0; c < 3; ++c) {
    int best = 0;
    for (int r = 1; r < 3; ++r) {
      if (std::abs(direction[3 * r + c]) > std::abs(direction[3 * best + c])) best = r;
    }
    code += direction[3 * best + c] > 0 ? "LPS"[best] : "RAI"[best];
  }
  return code;
}

std::optional<std::array<double, 9>> DirectionOfCode(std::string_view code) {
  if (code.size() != 3) return std::nullopt;
  std::array<double, 9> d{};
  bool used[3] = {};
  for (int c = 0; c < 3; ++c) {
    const char letter = char(std::toupper(static_cast<unsigned char>(code[c])));
    const std::string_view positive = "LPS", negative = "RAI";
    const std::size_t at =
        positive.find(letter) != std::string_view::npos ? positive.find(letter) : negative.find(letter);
    if (at == std::string_view::npos || used[at]) return std::nullopt;
    used[at] = true;
    d[3 * at + c] = positive.find(letter) != std::string_view::npos ? 1.0 : -1.0;
  }
  return d;
}

template <class T>
void Volume::Store(MemoryBlock voxels) {
  const std::size_t n = voxel_count();
  const ValueScan scan = Scan(static_cast<const T*>(voxels.data()), n);
  if (scan.beyond != 0) {
    throw InputError(
        fmt::format("{}: a voxel value of {:g} is beyond what cinevol holds: values must lie within "
                    "[{:g}, {:g}]",
                    metadata_.source, scan.beyond, -kMaxVoxelMagnitude, kMaxVoxelMagnitude));
  }
  metadata_.non_finite_replaced = scan.non_finite;
  metadata_.subnormals_flushed = scan.subnormal;
  min_value_ = float(scan.lo);
  max_value_ = float(scan.hi);
  const float lo = min_value_, hi = max_value_;
  if (scan.integral && scan.hi - scan.lo <= 65535.0) {
    storage_ = VoxelStorage::kUInt16;
    stored_offset_ = lo;
    const double offset = scan.lo;
    voxels_ = ConvertBlock<T, std::uint16_t>(std::move(voxels), n, [=](T v) {
      // From the value itself where it is finite: through float, integers
      // past 2^24 round, to below the offset too.
      bool finite = true;
      if constexpr (std::is_floating_point_v<T>) finite = std::isfinite(v);
      const double exact = finite ? double(v) : double(Sanitised(v, lo, hi));
      return static_cast<std::uint16_t>(std::clamp(std::nearbyint(exact - offset), 0.0, 65535.0));
    });
  } else {
    storage_ = VoxelStorage::kFloat32;
    voxels_ = ConvertBlock<T, float>(std::move(voxels), n, [=](T v) { return Sanitised(v, lo, hi); });
  }
}

ValuesView<std::uint16_t> Volume::u16() const {
  if (storage_ != VoxelStorage::kUInt16) return {};
  return {static_cast<const std::uint16_t*>(voxels_.data()), voxel_count()};
}

ValuesView<float> Volume::f32() const {
  if (storage_ != VoxelStorage::kFloat32) return {};
  return {static_cast<const float*>(voxels_.data()), voxel_count()};
}

std::uint64_t Volume::BytesToLoad(VoxelType type, std::uint64_t voxels) {
  const std::uint64_t block = std::max<std::uint64_t>(BytesPerVoxel(type), sizeof(std::uint16_t));
  // 8-bit voxels widen into a new 16-bit block while the reader's is held.
  const std::uint64_t widening = BytesPerVoxel(type) == 1 ? voxels : 0;
  const std::uint64_t blocks =
      (voxels + kBlockSize * kBlockSize * kBlockSize - 1) / (kBlockSize * kBlockSize * kBlockSize);
  return voxels * block + widening + blocks * sizeof(ValueRange);
}

Vec3i Volume::block_counts() const { return BlockCounts(dims_, {kBlockSize, kBlockSize, kBlockSize}); }

std::size_t Volume::voxel_count() const { return std::size_t(dims_.x) * std::size_t(dims_.y) * std::size_t(dims_.z); }

float Volume::ValueAtIndex(std::size_t i) const {
  return storage_ == VoxelStorage::kUInt16 ? float(u16()[i]) + stored_offset_ : f32()[i];
}

float Volume::Value(int x, int y, int z) const { return ValueAtIndex((std::size_t(z) * dims_.y + y) * dims_.x + x); }

std::size_t Volume::MemoryBytes() const {
  return voxels_.bytes() + block_ranges_.size() * sizeof(ValueRange) + histogram_.counts.size() * sizeof(std::uint64_t);
}

}  // namespace cinevol

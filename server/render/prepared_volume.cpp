// Preparing volumes once, and the cache that shares them.
#include "render/prepared_volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "core/blocks.h"
#include "core/parallel_for.h"

namespace cinevol {

BrickRanges ComputeBrickRanges(const std::uint16_t* voxels, Vec3i dims, Vec3i brick_size, int margin) {
  BrickRanges r;
  r.bricks = BlockCounts(dims, brick_size);
  r.min.assign(BlockTotal(r.bricks), 0xffff);
  r.max.assign(BlockTotal(r.bricks), 0);
  ForEachBlock(dims, brick_size, margin, [&](std::size_t i, Vec3i lo, Vec3i hi) {
    std::uint16_t mn = 0xffff, mx = 0;
    ForEachVoxel(voxels, dims, lo, hi, [&](std::uint16_t v) {
      mn = std::min(mn, v);
      mx = std::max(mx, v);
    });
    r.min[i] = mn;
    r.max[i] = mx;
  });
  return r;
}

int BrickSizeFor(Vec3f spacing_mm, std::size_t voxels) {
  const bool coarse = float(kDefaultBrickSize) * MinComponent(spacing_mm) > kMaxBrickMm;
  return coarse && voxels <= kMaxVoxels / 8 ? 2 : kDefaultBrickSize;
}

PreparedVolume::PreparedVolume(std::shared_ptr<const Volume> volume, int brick_size) : volume_(std::move(volume)) {
  const Volume& v = *volume_;
  if (v.storage() == VoxelStorage::kUInt16) {
    voxels_ = v.u16().data();
    value_offset_ = v.stored_offset();
  } else {
    const float range = v.max_value() - v.min_value();
    // A step of at least the smallest normal float: a range narrower than
    // 65535 of them (below 7.7e-34) takes fewer levels rather than a
    // subnormal scale, which GPUs flush to 0.
    value_scale_ = range > 0 ? std::max(range / 65535.0f, std::numeric_limits<float>::min()) : 1.0f;
    value_offset_ = v.min_value();
    quantised_.resize(v.voxel_count());
    const ValuesView<float> f = v.f32();
    ParallelFor(std::int64_t(f.size()), [&](std::int64_t i) {
      const long level = std::lround((f[i] - value_offset_) / value_scale_);
      quantised_[i] = static_cast<std::uint16_t>(std::clamp(level, 0L, 65535L));
    }, 0, 1 << 16);
    voxels_ = quantised_.data();
  }
  if (brick_size == kAutoBrickSize) brick_size = BrickSizeFor(v);
  brick_size_ = brick_size > 0 ? Vec3i{brick_size, brick_size, brick_size} : v.dims();
  bricks_ = ComputeBrickRanges(voxels_, v.dims(), brick_size_, LookupMargin(Reconstruction::kTrilinear));
  cubic_bricks_ = ComputeBrickRanges(voxels_, v.dims(), brick_size_, LookupMargin(Reconstruction::kTricubic));
}

std::size_t PreparedVolume::host_bytes() const {
  return (quantised_.size() + 2 * (bricks_.min.size() + bricks_.max.size())) * sizeof(std::uint16_t);
}

BrickLabels ComputeBrickLabels(const LabelVolume& labels, Vec3i brick_size) {
  // Per brick its distinct labels, found in parallel, then packed.
  std::vector<std::vector<std::uint16_t>> found(BlockTotal(BlockCounts(labels.dims, brick_size)));
  ForEachBlock(labels.dims, brick_size, 1, [&](std::size_t i, Vec3i lo, Vec3i hi) {
    std::vector<std::uint16_t>& seen = found[i];
    ForEachVoxel(labels.labels.data(), labels.dims, lo, hi, [&](std::uint16_t v) {
      if (std::find(seen.begin(), seen.end(), v) == seen.end()) seen.push_back(v);
    });
  });
  BrickLabels out;
  out.offsets.reserve(found.size() + 1);
  out.offsets.push_back(0);
  for (const auto& f : found) {
    out.labels.insert(out.labels.end(), f.begin(), f.end());
    out.offsets.push_back(static_cast<std::uint32_t>(out.labels.size()));
  }
  return out;
}

LabelCopy::LabelCopy(std::shared_ptr<const LabelVolume> labels, Vec3i brick_size, int device)
    : labels_(std::move(labels)), bricks_(ComputeBrickLabels(*labels_, brick_size)) {
  if (device == kHostDevice) return;
#if CINEVOL_WITH_CUDA
  gpu_ = UploadLabels(*labels_, device);
#else
  throw std::logic_error("LabelCopy: a GPU copy in a build without CUDA");
#endif
}

const std::uint16_t* LabelCopy::voxels() const { return gpu_ ? gpu_.get() : labels_->labels.data(); }

std::string DeviceLabel(int device) { return device == kHostDevice ? "cpu" : "cuda:" + std::to_string(device); }

VolumeCopy::VolumeCopy(std::shared_ptr<const PreparedVolume> prepared, int device, [[maybe_unused]] bool texture)
    : prepared_(std::move(prepared)), device_(device) {
  if (device_ == kHostDevice) return;
#if CINEVOL_WITH_CUDA
  gpu_ = UploadVoxels(*prepared_, device_, texture);
#else
  throw std::logic_error("VolumeCopy: a GPU copy in a build without CUDA");
#endif
}

const std::uint16_t* VolumeCopy::voxels() const {
  return device_ == kHostDevice ? prepared_->voxels() : gpu_->buffer;
}

std::size_t VolumeCopy::bytes() const {
  return device_ == kHostDevice ? prepared_->host_bytes() : gpu_->bytes;
}

VolumeCache& VolumeCache::Get() {
  static VolumeCache cache;
  return cache;
}

template <class Key, class T>
void VolumeCache::PruneLocked(Slots<Key, T>& slots) {
  // A slot nobody else holds (use_count 1: no build under way) whose value is gone.
  std::erase_if(slots,
                [](const auto& entry) { return entry.second.use_count() == 1 && entry.second->value.expired(); });
}

template <class Key, class T, class Make>
std::shared_ptr<const T> VolumeCache::FindOrMake(Slots<Key, T>& slots, const Key& key, Make make) {
  std::shared_ptr<Slot<T>> slot;
  {
    std::lock_guard lock(mu_);
    PruneLocked(slots);
    std::shared_ptr<Slot<T>>& s = slots[key];
    if (!s) s = std::make_shared<Slot<T>>();
    slot = s;
  }
  // Only callers for this key wait while it is built (an upload can take a
  // while); other volumes and devices go on.
  std::lock_guard build(slot->build);
  if (std::shared_ptr<const T> value = slot->value.lock()) return value;
  std::shared_ptr<const T> value = make();
  std::lock_guard lock(mu_);
  slot->value = value;
  if constexpr (std::is_same_v<T, VolumeCopy>) slot->bytes = value->bytes();
  return value;
}

std::shared_ptr<const VolumeCopy> VolumeCache::Acquire(const std::shared_ptr<const Volume>& volume, int brick_size,
                                                       int device, bool texture) {
  texture = texture && device != kHostDevice;  // the host has one kind of copy
  if (brick_size == kAutoBrickSize) brick_size = BrickSizeFor(*volume);
  return FindOrMake(copies_, std::tuple{device, volume.get(), brick_size, texture}, [&] {
    std::shared_ptr<const PreparedVolume> prepared = FindOrMake(prepared_, std::tuple{volume.get(), brick_size}, [&] {
      return std::make_shared<const PreparedVolume>(volume, brick_size);
    });
    return std::make_shared<const VolumeCopy>(std::move(prepared), device, texture);
  });
}

std::shared_ptr<const LabelCopy> VolumeCache::AcquireLabels(const std::shared_ptr<const LabelVolume>& labels,
                                                            Vec3i brick_size, int device) {
  return FindOrMake(labels_, std::tuple{device, labels.get(), brick_size.x},
                    [&] { return std::make_shared<const LabelCopy>(labels, brick_size, device); });
}

std::shared_ptr<const std::vector<float>> VolumeCache::AcquireMajorants(
    const MajorantKey& key, const std::function<std::vector<float>()>& build) {
  return FindOrMake(majorants_, key, [&] { return std::make_shared<const std::vector<float>>(build()); });
}

#if CINEVOL_WITH_CUDA
std::shared_ptr<const float> VolumeCache::AcquireMajorantsOnGpu(
    const std::shared_ptr<const std::vector<float>>& majorants, int gpu) {
  // The device copy holds the host one: its key's address stays that set's.
  return FindOrMake(gpu_majorants_, std::tuple{gpu, majorants.get()}, [&] {
    std::shared_ptr<const float> uploaded = UploadMajorants(*majorants, gpu);
    // The deleter lets go of both when the last renderer does (the cache's
    // weak reference keeps a deleter, and what it holds, alive until then).
    return std::shared_ptr<const float>(uploaded.get(), [uploaded, held = majorants](const float*) mutable {
      uploaded.reset();
      held.reset();
    });
  });
}
#endif

std::size_t VolumeCache::MajorantSets() const {
  std::lock_guard lock(mu_);
  std::size_t n = 0;
  for (const auto& [key, slot] : majorants_) n += slot->value.use_count() > 0;
  for (const auto& [key, slot] : gpu_majorants_) n += slot->value.use_count() > 0;
  return n;
}

std::vector<VolumeCopyStatus> VolumeCache::Copies() const {
  std::lock_guard lock(mu_);
  std::vector<VolumeCopyStatus> out;
  for (const auto& [key, slot] : copies_) {
    const long renderers = slot->value.use_count();
    if (renderers > 0) out.push_back({std::get<1>(key), std::get<0>(key), slot->bytes, renderers});
  }
  return out;
}

}  // namespace cinevol

// Volumes ready to render, shared by every renderer that draws them. A
// PreparedVolume (16-bit voxels, the value mapping, per-brick value ranges) is
// built once per Volume and brick size; a VolumeCopy puts it on one device (on
// a GPU: the voxels uploaded once). Every renderer of a volume on a device
// holds the same copy through VolumeCache, which keeps only weak references:
// the copy goes with its last renderer.
//
// What stays per renderer is what depends on the session: the transfer table,
// the majorants it implies, lights, frame buffers (scene_data.h, renderers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "core/labels.h"
#include "core/volume.h"
#include "core/volume_view.h"

namespace cinevol {

// Bricks are this many voxels along each axis for most volumes: 4^3 measured
// faster than 8^3 and 16^3 on CPU and GPU (docs/performance.md).
inline constexpr int kDefaultBrickSize = 4;
// A brick size that asks for BrickSizeFor(volume): RendererOptions' default.
inline constexpr int kAutoBrickSize = -1;
// Bricks wider than this along the volume's finest axis bound too much at
// once: a coarse scan's 4^3 bricks mix vessels and bone with the fat around
// them, and its paths take many tentative collisions.
inline constexpr float kMaxBrickMm = 5.0f;
// kDefaultBrickSize voxels, or 2 where those would span more than kMaxBrickMm
// (voxels coarser than 1.25 mm): 2^3 bricks measured 15-24% faster on CTs of
// 1.5 and 3 mm voxels, 4^3 9-10% faster on heads of 0.9-1 mm
// (docs/performance.md, "Brick size from the voxel spacing"). Only volumes
// of at most kMaxVoxels / 8 voxels take 2^3: their bricks are then never
// more than 4^3 bricks of the largest volume, so the brick ranges and
// majorants stay within the memory they took before.
int BrickSizeFor(Vec3f spacing_mm, std::size_t voxels);
inline int BrickSizeFor(const Volume& volume) { return BrickSizeFor(volume.spacing_mm(), volume.voxel_count()); }

// Min and max stored value of each brick, including the margin that lookups
// inside the brick read (one voxel for trilinear, two for tricubic). (Volume::block_ranges is
// another thing: float values without the margin, for framing what a transfer
// function shows; majorants from it would not bound trilinear lookups.)
struct BrickRanges {
  Vec3i bricks;
  std::vector<std::uint16_t> min, max;
};

BrickRanges ComputeBrickRanges(const std::uint16_t* voxels, Vec3i dims, Vec3i brick_size, int margin);

// Immutable once built: safe to read from any thread.
class PreparedVolume {
 public:
  // Quantises float volumes to 16 bits over their range; 16-bit volumes are
  // used as they are. brick_size voxels per brick edge (kAutoBrickSize:
  // BrickSizeFor); 0: one brick spanning the volume (empty-space skipping
  // off, to measure what bricks buy).
  PreparedVolume(std::shared_ptr<const Volume> volume, int brick_size);

  const Volume& volume() const { return *volume_; }
  const std::uint16_t* voxels() const { return voxels_; }  // host memory
  // value = stored * value_scale + value_offset
  float value_scale() const { return value_scale_; }
  float value_offset() const { return value_offset_; }
  Vec3i brick_size() const { return brick_size_; }
  const BrickRanges& brick_ranges(Reconstruction r) const {
    return r == Reconstruction::kTricubic ? cubic_bricks_ : bricks_;
  }
  // Host memory this adds to the Volume's own: a float volume's quantised
  // voxels and the brick ranges.
  std::size_t host_bytes() const;

 private:
  std::shared_ptr<const Volume> volume_;
  std::vector<std::uint16_t> quantised_;  // float volumes only
  const std::uint16_t* voxels_ = nullptr;
  float value_scale_ = 1, value_offset_ = 0;
  Vec3i brick_size_;
  BrickRanges bricks_, cubic_bricks_;  // trilinear and tricubic margins
};

// The labels present in each brick of `brick_size` voxels, with the one-voxel
// margin that nearest-label lookups inside the brick read: labels of brick i
// are labels[offsets[i] .. offsets[i + 1]).
struct BrickLabels {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint16_t> labels;
};
BrickLabels ComputeBrickLabels(const LabelVolume& labels, Vec3i brick_size);

// The device of CPU renderers: their copy is the PreparedVolume in host memory.
inline constexpr int kHostDevice = -1;

// "cpu" for kHostDevice, "cuda:N" for GPU N.
std::string DeviceLabel(int device);

// A prepared volume's voxels on one GPU, held once: a 3D texture where one
// fits (the path tracer samples through it), else a buffer (volumes too large
// for a texture, RendererOptions::volume_texture off).
struct GpuVoxels {
  const std::uint16_t* buffer = nullptr;  // null with a texture
  unsigned long long texture = 0;         // cudaTextureObject_t; 0 with a buffer
  std::size_t bytes = 0;
};

// A prepared volume on one device: kHostDevice or a GPU ordinal. Immutable.
class VolumeCopy {
 public:
  // On a GPU, uploads the voxels there, as a texture when `texture` and one
  // fits (throws ResourceExhausted when they do not fit the GPU's memory).
  VolumeCopy(std::shared_ptr<const PreparedVolume> prepared, int device, bool texture = true);

  const PreparedVolume& prepared() const { return *prepared_; }
  const std::shared_ptr<const PreparedVolume>& prepared_ptr() const { return prepared_; }
  int device() const { return device_; }
  const std::uint16_t* voxels() const;  // in the device's memory; null on a GPU holding a texture
  // On a GPU, the voxels also as a 3D texture (device/volume_texture.h) when
  // they fit the GPU's texture size; 0 otherwise.
  unsigned long long texture() const { return gpu_ ? gpu_->texture : 0; }
  // Memory this copy takes on its device: the uploaded voxels on a GPU, the
  // prepared volume's host_bytes on the host.
  std::size_t bytes() const;

 private:
  std::shared_ptr<const PreparedVolume> prepared_;
  int device_;
  std::shared_ptr<const GpuVoxels> gpu_;  // freed on its GPU with the last owner
};

// A segmentation on one device, shared like a VolumeCopy by every renderer
// of it there: the labels present in each brick (host memory, for the
// majorants) and the label voxels (on a GPU, uploaded once). Immutable.
class LabelCopy {
 public:
  LabelCopy(std::shared_ptr<const LabelVolume> labels, Vec3i brick_size, int device);

  const LabelVolume& labels() const { return *labels_; }
  const BrickLabels& brick_labels() const { return bricks_; }
  const std::uint16_t* voxels() const;  // in the device's memory

 private:
  std::shared_ptr<const LabelVolume> labels_;
  BrickLabels bricks_;
  std::shared_ptr<const std::uint16_t> gpu_;  // freed on its GPU with the last owner
};

// What a volume's majorants depend on beyond its prepared bricks: the
// reconstruction (its margin), the segmentation and the extinction each label
// value gets (every transfer table's, each value's opacity scale and table).
// Renderers whose keys are equal share one set of majorants.
struct MajorantKey {
  const PreparedVolume* volume = nullptr;
  Reconstruction reconstruction = Reconstruction::kTrilinear;
  const LabelCopy* labels = nullptr;
  std::vector<float> sigma_t;       // every table's extinctions, as TransferTable holds them
  std::vector<float> label_scales;  // per label value: opacity scale, table index

  bool operator<(const MajorantKey& o) const {
    return std::tie(volume, reconstruction, labels, sigma_t, label_scales) <
           std::tie(o.volume, o.reconstruction, o.labels, o.sigma_t, o.label_scales);
  }
};

#if CINEVOL_WITH_CUDA
// Copies the prepared voxels to GPU `gpu`; the pointer frees them there (from
// any thread). Defined in volume_upload.cu.
std::shared_ptr<const GpuVoxels> UploadVoxels(const PreparedVolume& prepared, int gpu, bool texture);
// The same for a segmentation's label voxels.
std::shared_ptr<const std::uint16_t> UploadLabels(const LabelVolume& labels, int gpu);
// The same for majorants.
std::shared_ptr<const float> UploadMajorants(const std::vector<float>& majorants, int gpu);
#endif

// One copy as the cache reports it.
struct VolumeCopyStatus {
  const Volume* volume;  // which volume: compare only, it may be gone by now
  int device;            // kHostDevice or a GPU ordinal
  std::size_t bytes;     // VolumeCopy::bytes
  long renderers;        // renderers holding the copy
};

class VolumeCache {
 public:
  // The process's cache: every session, still and offline render shares it.
  static VolumeCache& Get();

  // The copy of `volume` with `brick_size` bricks (kAutoBrickSize:
  // BrickSizeFor) on `device`, built on first use. Thread-safe: callers
  // asking for the same copy at once get one copy, built once; only they
  // wait for it.
  // `texture`: on a GPU, held as a texture where one fits (RendererOptions::volume_texture).
  std::shared_ptr<const VolumeCopy> Acquire(const std::shared_ptr<const Volume>& volume, int brick_size, int device,
                                            bool texture = true);
  // The same for a segmentation, with the prepared volume's brick size.
  std::shared_ptr<const LabelCopy> AcquireLabels(const std::shared_ptr<const LabelVolume>& labels, Vec3i brick_size,
                                                 int device);

  // The majorants of `key`, made by `build` on first use and shared while
  // any renderer holds them: sessions of one volume with one classification
  // build and hold them once.
  std::shared_ptr<const std::vector<float>> AcquireMajorants(const MajorantKey& key,
                                                             const std::function<std::vector<float>()>& build);
#if CINEVOL_WITH_CUDA
  // Shared majorants on GPU `gpu`, uploaded once.
  std::shared_ptr<const float> AcquireMajorantsOnGpu(const std::shared_ptr<const std::vector<float>>& majorants,
                                                     int gpu);
#endif

  // The live copies, by device then volume.
  std::vector<VolumeCopyStatus> Copies() const;
  // Sets of majorants held, on the host (shared by CPU and CUDA renderers)
  // and on GPUs.
  std::size_t MajorantSets() const;

 private:
  // One key's value; `build` serialises building it, the cache's lock guards
  // `value` (held weakly: the users own it).
  template <class T>
  struct Slot {
    std::mutex build;
    std::weak_ptr<const T> value;
    std::size_t bytes = 0;
  };
  template <class Key, class T>
  using Slots = std::map<Key, std::shared_ptr<Slot<T>>>;

  template <class Key, class T, class Make>
  std::shared_ptr<const T> FindOrMake(Slots<Key, T>& slots, const Key& key, Make make);
  template <class Key, class T>
  static void PruneLocked(Slots<Key, T>& slots);

  mutable std::mutex mu_;
  Slots<std::tuple<const Volume*, int>, PreparedVolume> prepared_;          // volume, brick size
  Slots<std::tuple<int, const Volume*, int, bool>, VolumeCopy> copies_;  // device, volume, brick size, texture
  Slots<std::tuple<int, const LabelVolume*, int>, LabelCopy> labels_;     // device, labels, brick size (x)
  Slots<MajorantKey, std::vector<float>> majorants_;
  Slots<std::tuple<int, const std::vector<float>*>, float> gpu_majorants_;  // device, host majorants
};

}  // namespace cinevol

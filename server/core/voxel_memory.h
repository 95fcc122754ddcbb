// Voxels as a reader hands them over: one block of memory and the type of
// its elements, so a 16-bit CT is never widened on its way in.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string_view>

namespace cinevol {

// A read-only view of `size()` values: std::span, which the CUDA build's
// C++17 lacks.
template <class T>
class ValuesView {
 public:
  ValuesView() = default;
  ValuesView(const T* data, std::size_t size) : data_(data), size_(size) {}
  template <class Container>
  ValuesView(const Container& c) : data_(c.data()), size_(c.size()) {}  // NOLINT: a view converts implicitly
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }

 private:
  const T* data_ = nullptr;
  std::size_t size_ = 0;
};

// The element types volume files hold (NIfTI, NRRD, MetaImage, VTK, DICOM).
enum class VoxelType : std::uint8_t {
  kUInt8,
  kInt8,
  kUInt16,
  kInt16,
  kUInt32,
  kInt32,
  kUInt64,
  kInt64,
  kFloat32,
  kFloat64
};

std::size_t BytesPerVoxel(VoxelType type);
const char* ToString(VoxelType type);  // "uint8", "int16", "float32", ...
std::optional<VoxelType> VoxelTypeNamed(std::string_view name);
bool IsInteger(VoxelType type);

// One block of memory that gives itself back when dropped: anonymous pages
// (untouched, so uncommitted, until written), a mapping made elsewhere (a
// reader's shared memory) or memory from the heap (a vector's). A copy is a
// fresh anonymous block.
class MemoryBlock {
 public:
  using Release = std::function<void(void* data, std::size_t bytes)>;
  // Whether the block's pages are its own (a mapping, shared memory
  // included) or the heap's, which other allocations share: only its own
  // pages may be given back by Shrink.
  enum class Pages { kOwn, kHeap };

  MemoryBlock() = default;
  // Takes `data` (`bytes` long), given back through `release`.
  MemoryBlock(void* data, std::size_t bytes, Pages pages, Release release);
  // Fresh anonymous pages; throws std::bad_alloc.
  static MemoryBlock Allocate(std::size_t bytes);
  ~MemoryBlock();
  MemoryBlock(MemoryBlock&& other) noexcept;
  MemoryBlock& operator=(MemoryBlock&& other) noexcept;
  MemoryBlock(const MemoryBlock& other);
  MemoryBlock& operator=(const MemoryBlock& other);

  void* data() const { return data_; }
  // The bytes in use: the whole block, or less after Shrink.
  std::size_t bytes() const { return bytes_; }
  // Keeps the first `bytes` (at most bytes()); where the pages are the
  // block's own, the whole pages past them go back to the system at once,
  // also for shared memory.
  void Shrink(std::size_t bytes);

 private:
  void* data_ = nullptr;
  std::size_t bytes_ = 0;
  std::size_t mapped_ = 0;  // what `release_` gives back
  Pages pages_ = Pages::kHeap;
  Release release_;
};

}  // namespace cinevol

// Voxel types and memory blocks.
#include "core/voxel_memory.h"

#include <sys/mman.h>
#include <unistd.h>

#include <cstring>
#include <new>
#include <utility>

namespace cinevol {
namespace {

struct TypeInfo {
  VoxelType type;
  const char* name;
  std::size_t bytes;
  bool integer;
};
constexpr TypeInfo kTypes[] = {
    {VoxelType::kUInt8, "uint8", 1, true},     {VoxelType::kInt8, "int8", 1, true},
    {VoxelType::kUInt16, "uint16", 2, true},   {VoxelType::kInt16, "int16", 2, true},
    {VoxelType::kUInt32, "uint32", 4, true},   {VoxelType::kInt32, "int32", 4, true},
    {VoxelType::kUInt64, "uint64", 8, true},   {VoxelType::kInt64, "int64", 8, true},
    {VoxelType::kFloat32, "float32", 4, false}, {VoxelType::kFloat64, "float64", 8, false},
};

const TypeInfo& Info(VoxelType type) { return kTypes[static_cast<int>(type)]; }

std::size_t PageSize() {
  static const std::size_t size = std::size_t(sysconf(_SC_PAGESIZE));
  return size;
}

}  // namespace

std::size_t BytesPerVoxel(VoxelType type) { return Info(type).bytes; }
const char* ToString(VoxelType type) { return Info(type).name; }
bool IsInteger(VoxelType type) { return Info(type).integer; }

std::optional<VoxelType> VoxelTypeNamed(std::string_view name) {
  for (const TypeInfo& t : kTypes) {
    if (name == t.name) return t.type;
  }
  return std::nullopt;
}

MemoryBlock::MemoryBlock(void* data, std::size_t bytes, Pages pages, Release release)
    : data_(data), bytes_(bytes), mapped_(bytes), pages_(pages), release_(std::move(release)) {}

MemoryBlock MemoryBlock::Allocate(std::size_t bytes) {
  if (bytes == 0) return {};
  void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  return {p, bytes, Pages::kOwn, [](void* data, std::size_t size) { munmap(data, size); }};
}

MemoryBlock::~MemoryBlock() {
  if (data_ && release_) release_(data_, mapped_);
}

MemoryBlock::MemoryBlock(MemoryBlock&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)),
      bytes_(std::exchange(other.bytes_, 0)),
      mapped_(std::exchange(other.mapped_, 0)),
      pages_(other.pages_),
      release_(std::move(other.release_)) {}

MemoryBlock::MemoryBlock(const MemoryBlock& other) : MemoryBlock(Allocate(other.bytes_)) {
  if (bytes_ > 0) std::memcpy(data_, other.data_, bytes_);
}

MemoryBlock& MemoryBlock::operator=(const MemoryBlock& other) {
  if (this != &other) *this = MemoryBlock(other);
  return *this;
}

MemoryBlock& MemoryBlock::operator=(MemoryBlock&& other) noexcept {
  if (this != &other) {
    MemoryBlock old(std::move(*this));
    data_ = std::exchange(other.data_, nullptr);
    bytes_ = std::exchange(other.bytes_, 0);
    mapped_ = std::exchange(other.mapped_, 0);
    pages_ = other.pages_;
    release_ = std::move(other.release_);
  }
  return *this;
}

void MemoryBlock::Shrink(std::size_t bytes) {
  if (bytes >= bytes_) return;
  bytes_ = bytes;
  // Heap memory shares its pages with other allocations and malloc's own
  // records, which advising the pages away would zero.
  if (pages_ != Pages::kOwn) return;
  const std::size_t page = PageSize();
  const std::size_t keep = (bytes + page - 1) / page * page;
  if (keep >= mapped_ || reinterpret_cast<std::uintptr_t>(data_) % page != 0) return;
  char* tail = static_cast<char*>(data_) + keep;
  // MADV_REMOVE frees shared memory's pages (a memfd's); private pages need MADV_DONTNEED.
  if (madvise(tail, mapped_ - keep, MADV_REMOVE) != 0) madvise(tail, mapped_ - keep, MADV_DONTNEED);
}

}  // namespace cinevol

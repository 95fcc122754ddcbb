#include "core/volume.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <numeric>

#include "core/error.h"

namespace cinevol {
namespace {

VolumeMetadata Named(const char* source) {
  VolumeMetadata m;
  m.source = source;
  return m;
}

TEST(Volume, IntegerHuFitsSixteenBits) {
  Volume v({2, 1, 1}, {1, 1, 1}, {-1024.0f, 3071.0f}, Named("t"));
  EXPECT_EQ(v.storage(), VoxelStorage::kUInt16);
  EXPECT_EQ(v.Value(0, 0, 0), -1024.0f);
  EXPECT_EQ(v.Value(1, 0, 0), 3071.0f);
  // The voxels, one block's value range and the histogram.
  EXPECT_EQ(v.MemoryBytes(), 4u + sizeof(Volume::ValueRange) + ValueHistogram::kBins * sizeof(std::uint64_t));
}

TEST(Volume, FractionalOrWideValuesStayFloat) {
  EXPECT_EQ(Volume({2, 1, 1}, {1, 1, 1}, {0.5f, 1.0f}, Named("t")).storage(), VoxelStorage::kFloat32);
  EXPECT_EQ(Volume({2, 1, 1}, {1, 1, 1}, {0.0f, 70000.0f}, Named("t")).storage(), VoxelStorage::kFloat32);
}

TEST(Volume, NonFiniteVoxelsAreReplacedAndCounted) {
  const float inf = std::numeric_limits<float>::infinity();
  Volume v({4, 1, 1}, {1, 1, 1}, {std::nanf(""), -inf, inf, 7.0f}, Named("t"));
  v.metadata();
  EXPECT_EQ(v.metadata().non_finite_replaced, 3u);
  EXPECT_EQ(v.Value(0, 0, 0), 7.0f);
  EXPECT_EQ(v.Value(2, 0, 0), 7.0f);
}

TEST(Volume, RejectsBadGeometryNamingTheSource) {
  EXPECT_THROW(Volume({0, 1, 1}, {1, 1, 1}, {}, Named("t")), InputError);
  EXPECT_THROW(Volume({1, 1, 1}, {0, 1, 1}, {1.0f}, Named("t")), InputError);
  EXPECT_THROW(Volume({1, 1, 1}, {std::nanf(""), 1, 1}, {1.0f}, Named("t")), InputError);
  try {
    CheckVolumeGeometry({8192, 8192, 8192}, {1, 1, 1}, "huge.nii");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.nii"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("exceeds the limit"), std::string::npos);
  }
}

TEST(Volume, RejectsValueCountMismatch) {
  EXPECT_THROW(Volume({2, 2, 1}, {1, 1, 1}, {1.0f, 2.0f}, Named("t")), InputError);
}

TEST(ValueHistogram, PercentilesAndTheThresholdBetweenTwoClasses) {
  // 3/4 of the voxels are background near 0, 1/4 subject spread over 600..1000.
  std::vector<float> values;
  for (int i = 0; i < 3000; ++i) values.push_back(float(i % 20));
  for (int i = 0; i < 1000; ++i) values.push_back(600.0f + 0.4f * float(i));
  const ValueHistogram h = ValueHistogram::Of(ValuesView<float>(values), 0.0f, 0.0f, 999.6f);
  EXPECT_EQ(std::accumulate(h.counts.begin(), h.counts.end(), std::uint64_t{0}), values.size());
  EXPECT_NEAR(h.Percentile(0.5), 13.0f, 8.0f);
  const float threshold = h.OtsuThreshold();
  EXPECT_GE(threshold, 19.0f);  // above every background value
  EXPECT_LE(threshold, 600.0f);
  EXPECT_NEAR(h.Percentile(0.5, threshold), 800.0f, 8.0f);  // the subject's median
  EXPECT_NEAR(h.Percentile(1.0, threshold), 999.6f, 4.0f);
}

TEST(ValueHistogram, ConstantVolumesHaveOneFullBin) {
  const Volume v({2, 2, 2}, {1, 1, 1}, std::vector<float>(8, 5.0f), Named("t"));
  EXPECT_EQ(v.histogram().counts[0], 8u);
  EXPECT_EQ(v.histogram().Percentile(0.5), 5.0f);
}

TEST(Volume, BlockRangesBoundEveryVoxel) {
  std::vector<float> values(20 * 9 * 3);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = float(i % 37);
  const Volume v({20, 9, 3}, {1, 1, 1}, values, Named("t"));
  EXPECT_EQ(v.block_counts(), (Vec3i{5, 3, 1}));
  for (int z = 0; z < 3; ++z) {
    for (int y = 0; y < 9; ++y) {
      for (int x = 0; x < 20; ++x) {
        const auto r = v.block_ranges()[(y / 4) * 5 + x / 4];
        EXPECT_LE(r.lo, v.Value(x, y, z));
        EXPECT_GE(r.hi, v.Value(x, y, z));
      }
    }
  }
}

// Values at the extremes (issue "No file can take the server down"): what
// Volume keeps, what it refuses, and what its histogram makes of them.

std::string RefusalOf(std::vector<float> values) {
  try {
    const int n = int(values.size());
    Volume({n, 1, 1}, {1, 1, 1}, std::move(values), Named("huge.nrrd"));
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

template <class T>
MemoryBlock BlockOf(std::vector<T> values) {
  MemoryBlock block = MemoryBlock::Allocate(values.size() * sizeof(T));
  std::memcpy(block.data(), values.data(), values.size() * sizeof(T));
  return block;
}

// A vector's memory shares its pages with the heap's other allocations and
// malloc's records: shrinking it gives no page back, so the memory past it
// keeps its contents. (Advising those pages away zeroed the heap's top chunk
// when a volume of floats, page-aligned by chance, was stored in 16 bits;
// malloc then aborted.)
TEST(MemoryBlock, ShrinkingHeapMemoryLeavesTheMemoryPastItAlone) {
  const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
  auto* heap = static_cast<unsigned char*>(std::aligned_alloc(page, 4 * page));
  ASSERT_NE(heap, nullptr);
  std::memset(heap, 0xab, 4 * page);
  const std::size_t end = 2 * page + 100;
  {
    MemoryBlock block(heap, end, MemoryBlock::Pages::kHeap, [](void*, std::size_t) {});
    block.Shrink(10);
    EXPECT_EQ(block.bytes(), 10u);
  }
  for (std::size_t i = 0; i < 10; ++i) ASSERT_EQ(heap[i], 0xab) << "kept byte " << i;
  for (std::size_t i = end; i < 4 * page; ++i) ASSERT_EQ(heap[i], 0xab) << "byte " << i - end << " past the block";
  std::free(heap);
}

// A block's own pages past what it keeps go back to the system.
TEST(MemoryBlock, ShrinkingItsOwnPagesGivesThemBack) {
  const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
  MemoryBlock block = MemoryBlock::Allocate(4 * page);
  std::memset(block.data(), 0xab, 4 * page);
  block.Shrink(10);
  const auto* bytes = static_cast<const unsigned char*>(block.data());
  EXPECT_EQ(bytes[9], 0xab);
  EXPECT_EQ(bytes[page], 0) << "the second page was not given back";
}

TEST(Volume, KeepsValuesUpToTheLargestMagnitudeExactly) {
  const Volume v({3, 1, 1}, {1, 1, 1}, {-kMaxVoxelMagnitude, 0.0f, kMaxVoxelMagnitude}, Named("t"));
  EXPECT_EQ(v.storage(), VoxelStorage::kFloat32);
  EXPECT_EQ(v.min_value(), -kMaxVoxelMagnitude);
  EXPECT_EQ(v.max_value(), kMaxVoxelMagnitude);
  EXPECT_EQ(v.Value(1, 0, 0), 0.0f);
}

TEST(Volume, RefusesFloatMaxNamingTheFileAndTheAllowedRange) {
  const float max = std::numeric_limits<float>::max();
  for (const std::vector<float>& values : {std::vector<float>{1.0f, max}, std::vector<float>{-max, 1.0f},
                                           std::vector<float>{0.0f, 1.01e30f}}) {
    const std::string message = RefusalOf(values);
    EXPECT_NE(message.find("huge.nrrd"), std::string::npos) << message;
    EXPECT_NE(message.find("[-1e+30, 1e+30]"), std::string::npos) << message;
  }
  // Doubles past float's range too, and they never reach float as infinities.
  try {
    Volume({2, 1, 1}, {1, 1, 1}, VoxelType::kFloat64, BlockOf<double>({1.0, 1e300}), Named("huge.nii"));
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("1e+300"), std::string::npos) << e.what();
  }
}

TEST(Volume, FlushesSubnormalsToZeroAndCountsThem) {
  const float smallest = std::numeric_limits<float>::denorm_min();
  const Volume v({4, 1, 1}, {1, 1, 1}, {1e-40f, -smallest, 2.5f, std::numeric_limits<float>::min()}, Named("t"));
  EXPECT_EQ(v.metadata().subnormals_flushed, 2u);
  EXPECT_EQ(v.Value(0, 0, 0), 0.0f);
  EXPECT_EQ(v.Value(1, 0, 0), 0.0f);
  EXPECT_EQ(v.Value(3, 0, 0), std::numeric_limits<float>::min());  // the smallest normal stays
  // Doubles below float's normal range are flushed too.
  const Volume d({2, 1, 1}, {1, 1, 1}, VoxelType::kFloat64, BlockOf<double>({1e-300, 3.0}), Named("t"));
  EXPECT_EQ(d.metadata().subnormals_flushed, 1u);
  EXPECT_EQ(d.Value(0, 0, 0), 0.0f);
}

TEST(Volume, ConstantVolumesAtTheLargestMagnitudeKeepTheirValue) {
  for (const float value : {kMaxVoxelMagnitude, -kMaxVoxelMagnitude, 0.5f, 0.0f}) {
    const Volume v({2, 2, 1}, {1, 1, 1}, std::vector<float>(4, value), Named("t"));
    EXPECT_EQ(v.min_value(), value);
    EXPECT_EQ(v.max_value(), value);
    EXPECT_EQ(v.Value(1, 1, 0), value);
    EXPECT_EQ(v.block_ranges()[0].lo, value);
  }
}

// Integers past float's 2^24 keep 16-bit storage when their span allows it,
// and each voxel keeps its value to float's precision: none wraps around
// the 16 bits (16777217 read as float rounds below the offset).
TEST(Volume, WideIntegersNearTheirTypesLimitsKeepTheirValues) {
  const Volume v({3, 1, 1}, {1, 1, 1}, VoxelType::kInt32, BlockOf<std::int32_t>({16777217, 16777219, 16777300}),
                 Named("t"));
  EXPECT_EQ(v.storage(), VoxelStorage::kUInt16);
  for (int x = 0; x < 3; ++x) {
    EXPECT_GE(v.Value(x, 0, 0), v.min_value());
    EXPECT_LE(v.Value(x, 0, 0), v.max_value());
  }
  EXPECT_NEAR(v.Value(0, 0, 0), 16777217.0, 2.0);
  EXPECT_NEAR(v.Value(1, 0, 0), 16777219.0, 2.0);
  EXPECT_NEAR(v.Value(2, 0, 0), 16777300.0, 2.0);
  const std::int64_t big = (std::int64_t{1} << 62) + 3 * (std::int64_t{1} << 38);
  const Volume w({2, 1, 1}, {1, 1, 1}, VoxelType::kInt64, BlockOf<std::int64_t>({big, big + 1000}), Named("t"));
  EXPECT_EQ(w.storage(), VoxelStorage::kUInt16);
  EXPECT_LE(w.Value(0, 0, 0), w.max_value());
  EXPECT_LE(w.Value(1, 0, 0), w.max_value());
  EXPECT_NEAR(w.Value(1, 0, 0), double(big), 1e-6 * double(big));
}

TEST(ValueHistogram, PercentilesAndOtsuStayInRangeAtTheExtremes) {
  const float m = kMaxVoxelMagnitude, tiny = std::numeric_limits<float>::min();
  const std::vector<std::vector<float>> cases = {
      {-m, -m, 0.0f, m},                  // the widest range
      {0.0f, tiny, tiny, 2 * tiny},       // the narrowest above zero
      std::vector<float>(8, m),           // constant, at the largest value
      std::vector<float>(8, -m),
      {42.0f},                            // one voxel
  };
  for (const std::vector<float>& values : cases) {
    const Volume v({int(values.size()), 1, 1}, {1, 1, 1}, values, Named("t"));
    const ValueHistogram& h = v.histogram();
    EXPECT_EQ(std::accumulate(h.counts.begin(), h.counts.end(), std::uint64_t{0}), values.size());
    for (const float f : {h.Percentile(0.0), h.Percentile(0.5), h.Percentile(0.995), h.Percentile(1.0),
                          h.OtsuThreshold(), h.Percentile(0.5, h.OtsuThreshold())}) {
      ASSERT_TRUE(std::isfinite(f)) << values[0];
      EXPECT_GE(f, v.min_value());
      EXPECT_LE(f, v.max_value());
    }
  }
  // The two classes of the widest range are told apart.
  std::vector<float> two(64, -m);
  for (int i = 0; i < 16; ++i) two[i] = m;
  const Volume v({64, 1, 1}, {1, 1, 1}, two, Named("t"));
  EXPECT_GT(v.histogram().OtsuThreshold(), -m);
  EXPECT_LT(v.histogram().OtsuThreshold(), m);
}

}  // namespace
}  // namespace cinevol

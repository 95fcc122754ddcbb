#include "core/volume.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

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
  EXPECT_EQ(v.MemoryBytes(), 4u);
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

}  // namespace
}  // namespace cinevol

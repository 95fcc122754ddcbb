#include "io/phantom.h"

#include <gtest/gtest.h>

#include "core/error.h"
#include "io/volume_loader.h"

namespace cinevol {
namespace {

TEST(Phantom, CubeFillsItsHalfEdge) {
  const Volume v = LoadVolume(ParseVolumeSpec("phantom:cube?size=8&value=500&background=-5&radius=2"));
  EXPECT_EQ(v.dims(), (Vec3i{8, 8, 8}));
  // Voxel centres at +-0.5, +-1.5 mm from the centre are inside |c| <= 2.
  EXPECT_EQ(v.Value(2, 2, 2), 500.0f);
  EXPECT_EQ(v.Value(5, 5, 5), 500.0f);
  EXPECT_EQ(v.Value(1, 4, 4), -5.0f);
  EXPECT_EQ(v.Value(4, 4, 6), -5.0f);
}

TEST(Phantom, SphereVoxelCountMatchesItsVolume) {
  const Volume v = LoadVolume(ParseVolumeSpec("phantom:sphere?size=64&radius=20&value=1"));
  std::size_t inside = 0;
  for (std::size_t i = 0; i < v.voxel_count(); ++i) inside += v.ValueAtIndex(i) == 1.0f;
  const double expected = 4.0 / 3.0 * M_PI * 20 * 20 * 20;
  EXPECT_NEAR(double(inside), expected, 0.01 * expected);
}

TEST(Phantom, HeadHasCtTissuesInHu) {
  const Volume v = LoadVolume(ParseVolumeSpec("phantom:head?size=128&spacing=2"));
  EXPECT_EQ(v.metadata().value_unit, "HU");
  EXPECT_EQ(v.storage(), VoxelStorage::kUInt16);
  auto at_mm = [&](float x, float y, float z) {  // LPS mm from the volume centre
    const float s = 2.0f, half = 128.0f;
    return v.Value(int((x + half) / s), int((y + half) / s), int((z + half) / s));
  };
  EXPECT_NEAR(at_mm(0, 0, 120), -1000, 20);   // air above the head
  EXPECT_NEAR(at_mm(0, 30, 60), 28, 20);      // white matter
  EXPECT_NEAR(at_mm(-11, 8, 32), 8, 20);      // lateral ventricle (CSF)
  EXPECT_GT(at_mm(0, 10, 103.5f), 1000);      // skull vertex: cortical bone
  EXPECT_NEAR(at_mm(-32, -74, -4), 12, 20);   // vitreous of the right eye... patient's right is -x
  EXPECT_GT(v.max_value(), 1300);
  EXPECT_LT(v.min_value(), -990);
}

TEST(Phantom, RejectsOutOfRangeParameters) {
  EXPECT_THROW(ParseVolumeSpec("phantom:cube?size=0"), InputError);
  EXPECT_THROW(ParseVolumeSpec("phantom:cube?size=2000"), InputError);
  EXPECT_THROW(ParseVolumeSpec("phantom:cube?colour=1"), InputError);
  EXPECT_THROW(ParseVolumeSpec("phantom:teapot"), InputError);
  EXPECT_THROW(LoadVolume(ParseVolumeSpec("phantom:cube?spacing=-1")), InputError);
  EXPECT_THROW(LoadVolume(ParseVolumeSpec("phantom:cube?spacing=0.00000001")), InputError);  // below 1e-4 mm
}

}  // namespace
}  // namespace cinevol

// Crop boxes and clip planes (issue 22): patient coordinates map to the
// renderer's half-spaces through the volume's origin and direction cosines.
// The renderer's side (exact chords, an empty crop) is in
// tests/render/integrator_test.cpp.
#include <gtest/gtest.h>

#include "io/phantom.h"
#include "scene/scene_builder.h"

namespace cinevol {
namespace {

bool Kept(const ClipRegion& region, Vec3f world) {
  for (int i = 0; i < region.count; ++i) {
    if (Dot(Xyz(region.half_spaces[i]), world) + region.half_spaces[i].w < 0.0f) return false;
  }
  return true;
}

// 10 x 20 x 30 voxels of 1 x 2 x 3 mm (a 10 x 40 x 90 mm box), stored with
// its first two index axes along the patient's right and anterior.
Volume FlippedVolume() {
  VolumeMetadata meta;
  meta.origin_mm = {100, 50, -20};
  meta.direction = {-1, 0, 0, 0, -1, 0, 0, 0, 1};
  return Volume({10, 20, 30}, {1, 2, 3}, std::vector<float>(10 * 20 * 30, 0.0f), meta);
}

// The patient position of the volume's centre: origin + D (extent - spacing) / 2.
v1::Vec3 CentreLps() {
  v1::Vec3 c;
  c.set_x(100 - 4.5f);
  c.set_y(50 - 19.0f);
  c.set_z(-20 + 43.5f);
  return c;
}

TEST(Clipping, APlaneThroughTheCentreKeepsTheHalfItFaces) {
  v1::Clipping clipping;
  v1::ClipPlane* plane = clipping.add_planes();
  *plane->mutable_point() = CentreLps();
  plane->mutable_normal()->set_x(1);  // keeps the patient's left: world -x here
  const ClipRegion region = ResolveClipping(clipping, FlippedVolume());
  ASSERT_EQ(region.count, 1);
  EXPECT_NEAR(region.half_spaces[0].x, -1.0f, 1e-6f);
  EXPECT_NEAR(region.half_spaces[0].w, 0.0f, 1e-4f);
  EXPECT_TRUE(Kept(region, {-1, 0, 0}));
  EXPECT_FALSE(Kept(region, {1, 0, 0}));
}

TEST(Clipping, ACropBoxKeepsItsInsideInPatientSpace) {
  v1::Clipping clipping;
  v1::CropBox* box = clipping.mutable_crop_box();
  *box->mutable_center() = CentreLps();
  box->mutable_center()->set_z(box->center().z() + 10);  // 10 mm superior
  box->mutable_size()->set_x(4);
  box->mutable_size()->set_y(8);
  box->mutable_size()->set_z(20);
  const ClipRegion region = ResolveClipping(clipping, FlippedVolume());
  ASSERT_EQ(region.count, 6);
  EXPECT_TRUE(Kept(region, {0, 0, 10}));
  EXPECT_TRUE(Kept(region, {1.9f, -3.9f, 19.9f}));
  EXPECT_FALSE(Kept(region, {0, 0, -0.1f}));  // below its inferior face
  EXPECT_FALSE(Kept(region, {2.1f, 0, 10}));
  EXPECT_FALSE(Kept(region, {0, 4.1f, 10}));
}

TEST(Clipping, AnOrientedBoxFollowsItsAxes) {
  v1::Clipping clipping;
  v1::CropBox* box = clipping.mutable_crop_box();
  *box->mutable_center() = CentreLps();
  box->mutable_size()->set_x(40);  // long along its x axis: the patient's L+P diagonal
  box->mutable_size()->set_y(2);
  box->mutable_size()->set_z(2);
  box->mutable_axis_x()->set_x(1);
  box->mutable_axis_x()->set_y(1);
  box->mutable_axis_y()->set_x(-1);
  box->mutable_axis_y()->set_y(1);
  const ClipRegion region = ResolveClipping(clipping, FlippedVolume());
  EXPECT_TRUE(Kept(region, {-10, -10, 0}));  // 14 mm along L+P (world -x, -y)
  EXPECT_FALSE(Kept(region, {-10, 10, 0}));
  EXPECT_FALSE(Kept(region, {-15, -15, 0}));  // 21 mm along: beyond half of 40
}

// A named view frames what the clipping keeps: a crop box around the middle
// of the head's left half brings the view closer and centres it there.
TEST(Clipping, NamedViewsFrameWhatIsKept) {
  v1::Phantom phantom;
  phantom.set_kind(v1::Phantom::HEAD);
  phantom.set_size(64);
  const Volume head = MakePhantom(phantom);
  v1::TransferFunction preset;
  preset.set_preset("ct-bone");
  const TransferFunction tf = ResolveTransferFunction(preset, head);
  v1::Camera anterior;
  anterior.set_view(v1::ANTERIOR);
  anterior.set_fov_y_deg(30);
  v1::RenderSettings render;
  render.set_width(64);
  render.set_height(64);
  v1::Clipping clipping;
  v1::CropBox* box = clipping.mutable_crop_box();
  // The phantom's axes are the patient's; its origin puts its centre at 0 mm.
  const auto& origin = head.metadata().origin_mm;
  const Vec3f centre = Vec3f{float(origin[0]), float(origin[1]), float(origin[2])} + head.extent_mm() * 0.5f -
                       head.spacing_mm() * 0.5f;
  box->mutable_center()->set_x(centre.x + head.extent_mm().x * 0.25f);  // the patient's left
  box->mutable_center()->set_y(centre.y);
  box->mutable_center()->set_z(centre.z);
  box->mutable_size()->set_x(head.extent_mm().x * 0.5f);
  box->mutable_size()->set_y(head.extent_mm().y * 0.5f);
  box->mutable_size()->set_z(head.extent_mm().z * 0.5f);
  const Camera whole = ResolveCamera(anterior, render, head, tf);
  InView kept;
  kept.clip = ResolveClipping(clipping, head);
  const Camera cropped = ResolveCamera(anterior, render, head, tf, kept);
  EXPECT_LT(cropped.focal_distance, 0.8f * whole.focal_distance) << "the view comes closer to the kept quarter";
  const Vec3f target = cropped.eye + cropped.forward * cropped.focal_distance;
  const Vec3f whole_target = whole.eye + whole.forward * whole.focal_distance;
  EXPECT_GT(target.x - whole_target.x, head.extent_mm().x * 0.05f) << "and moves to it (world +x: the patient's left)";
}

TEST(Clipping, NoClippingKeepsEverything) {
  EXPECT_EQ(ResolveClipping(v1::Clipping{}, FlippedVolume()).count, 0);
}

}  // namespace
}  // namespace cinevol

// The viewer's transfer function edits: points stay strictly ordered and in
// range, new points take their neighbours' material, at least two points
// remain, window/level shifts and scales, and evaluation holds beyond the ends.
#include "viewer/transfer_edits.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace cinevol::viewer {
namespace {

v1::Color Rgb(float r, float g, float b) {
  v1::Color c;
  c.set_r(r);
  c.set_g(g);
  c.set_b(b);
  return c;
}

v1::TransferFunctionPoint Point(float value, float opacity, const v1::Color& diffuse) {
  v1::TransferFunctionPoint p;
  p.set_value(value);
  p.set_opacity(opacity);
  *p.mutable_diffuse() = diffuse;
  return p;
}

// Three points over [0, 100]: red transparent, green half, blue opaque.
v1::TransferFunction ThreePoints() {
  v1::TransferFunction tf;
  tf.set_preset("ct-bone");
  *tf.add_points() = Point(0, 0, Rgb(1, 0, 0));
  *tf.add_points() = Point(50, 0.5f, Rgb(0, 1, 0));
  *tf.add_points() = Point(100, 1, Rgb(0, 0, 1));
  return tf;
}

void ExpectStrictlyIncreasing(const v1::TransferFunction& tf) {
  for (int i = 1; i < tf.points_size(); ++i)
    EXPECT_LT(tf.points(i - 1).value(), tf.points(i).value()) << "point " << i;
}

void ExpectColor(const v1::Color& c, float r, float g, float b) {
  EXPECT_NEAR(c.r(), r, 1e-6f);
  EXPECT_NEAR(c.g(), g, 1e-6f);
  EXPECT_NEAR(c.b(), b, 1e-6f);
}

TEST(MoveTransferPoint, MovesWithinNeighboursAndClearsPreset) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(MoveTransferPoint(tf, 1, 30, 0.25f));
  EXPECT_FLOAT_EQ(tf.points(1).value(), 30);
  EXPECT_FLOAT_EQ(tf.points(1).opacity(), 0.25f);
  EXPECT_TRUE(tf.preset().empty());
}

TEST(MoveTransferPoint, ValueStopsStrictlyInsideNeighbours) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(MoveTransferPoint(tf, 1, 500, 0.5f));
  EXPECT_LT(tf.points(1).value(), 100);
  EXPECT_GT(tf.points(1).value(), 99);
  ASSERT_TRUE(MoveTransferPoint(tf, 1, -500, 0.5f));
  EXPECT_GT(tf.points(1).value(), 0);
  EXPECT_LT(tf.points(1).value(), 1);
  ExpectStrictlyIncreasing(tf);
}

TEST(MoveTransferPoint, EndPointsMoveFreelyOutward) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(MoveTransferPoint(tf, 0, -1000, 0));
  ASSERT_TRUE(MoveTransferPoint(tf, 2, 3000, 1));
  EXPECT_FLOAT_EQ(tf.points(0).value(), -1000);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 3000);
  ASSERT_TRUE(MoveTransferPoint(tf, 0, 60, 0));  // past its neighbour at 50
  ExpectStrictlyIncreasing(tf);
}

TEST(MoveTransferPoint, OpacityClampedToUnitInterval) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(MoveTransferPoint(tf, 1, 50, 1.7f));
  EXPECT_FLOAT_EQ(tf.points(1).opacity(), 1);
  ASSERT_TRUE(MoveTransferPoint(tf, 1, 50, -0.3f));
  EXPECT_FLOAT_EQ(tf.points(1).opacity(), 0);
}

TEST(MoveTransferPoint, BadIndexOrNonFiniteChangesNothing) {
  v1::TransferFunction tf = ThreePoints();
  const std::string before = tf.SerializeAsString();
  EXPECT_FALSE(MoveTransferPoint(tf, -1, 10, 0.5f));
  EXPECT_FALSE(MoveTransferPoint(tf, 3, 10, 0.5f));
  EXPECT_FALSE(MoveTransferPoint(tf, 1, std::nanf(""), 0.5f));
  EXPECT_EQ(tf.SerializeAsString(), before);
}

TEST(AddTransferPoint, InsertsInOrderWithInterpolatedMaterial) {
  v1::TransferFunction tf = ThreePoints();
  tf.mutable_points(0)->set_roughness(0.2f);
  tf.mutable_points(1)->set_roughness(0.6f);
  *tf.mutable_points(0)->mutable_specular() = Rgb(0.1f, 0.1f, 0.1f);
  *tf.mutable_points(1)->mutable_specular() = Rgb(0.5f, 0.5f, 0.5f);
  *tf.mutable_points(1)->mutable_emission() = Rgb(2, 0, 0);
  const int index = AddTransferPoint(tf, 25, 0.9f);
  ASSERT_EQ(index, 1);
  ASSERT_EQ(tf.points_size(), 4);
  ExpectStrictlyIncreasing(tf);
  const v1::TransferFunctionPoint& p = tf.points(1);
  EXPECT_FLOAT_EQ(p.value(), 25);
  EXPECT_FLOAT_EQ(p.opacity(), 0.9f);
  ExpectColor(p.diffuse(), 0.5f, 0.5f, 0);
  ExpectColor(p.specular(), 0.3f, 0.3f, 0.3f);
  EXPECT_NEAR(p.roughness(), 0.4f, 1e-6f);
  ExpectColor(p.emission(), 1, 0, 0);
  EXPECT_TRUE(tf.preset().empty());
}

TEST(AddTransferPoint, BeyondTheEndsCopiesTheNearestEnd) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_EQ(AddTransferPoint(tf, -10, 0.1f), 0);
  ExpectColor(tf.points(0).diffuse(), 1, 0, 0);
  ASSERT_EQ(AddTransferPoint(tf, 200, 0.1f), 4);
  ExpectColor(tf.points(4).diffuse(), 0, 0, 1);
  ExpectStrictlyIncreasing(tf);
}

TEST(AddTransferPoint, ExistingValueIsRefused) {
  v1::TransferFunction tf = ThreePoints();
  EXPECT_EQ(AddTransferPoint(tf, 50, 0.3f), -1);
  EXPECT_EQ(tf.points_size(), 3);
  EXPECT_EQ(tf.preset(), "ct-bone");
}

TEST(AddTransferPoint, OpacityClampedToUnitInterval) {
  v1::TransferFunction tf = ThreePoints();
  EXPECT_FLOAT_EQ(tf.points(AddTransferPoint(tf, 75, 4)).opacity(), 1);
  EXPECT_FLOAT_EQ(tf.points(AddTransferPoint(tf, 80, -4)).opacity(), 0);
}

TEST(AddTransferPoint, EmptyFunctionGetsANeutralPoint) {
  v1::TransferFunction tf;
  tf.set_preset("ct-bone");
  ASSERT_EQ(AddTransferPoint(tf, 10, 0.5f), 0);
  ExpectColor(tf.points(0).diffuse(), 1, 1, 1);
  EXPECT_TRUE(tf.preset().empty());
}

TEST(DeleteTransferPoint, RemovesThePointAndKeepsOrder) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(DeleteTransferPoint(tf, 1));
  ASSERT_EQ(tf.points_size(), 2);
  EXPECT_FLOAT_EQ(tf.points(0).value(), 0);
  EXPECT_FLOAT_EQ(tf.points(1).value(), 100);
}

TEST(DeleteTransferPoint, KeepsAtLeastTwoPoints) {
  v1::TransferFunction tf = ThreePoints();
  ASSERT_TRUE(DeleteTransferPoint(tf, 0));
  EXPECT_FALSE(DeleteTransferPoint(tf, 0));
  EXPECT_FALSE(DeleteTransferPoint(tf, 1));
  EXPECT_EQ(tf.points_size(), 2);
}

TEST(DeleteTransferPoint, BadIndexIsRefused) {
  v1::TransferFunction tf = ThreePoints();
  EXPECT_FALSE(DeleteTransferPoint(tf, -1));
  EXPECT_FALSE(DeleteTransferPoint(tf, 3));
  EXPECT_EQ(tf.points_size(), 3);
}

TEST(ApplyWindowLevel, LevelShiftsEveryPoint) {
  v1::TransferFunction tf = ThreePoints();
  ApplyWindowLevel(tf, 40, 1);
  EXPECT_FLOAT_EQ(tf.points(0).value(), 40);
  EXPECT_FLOAT_EQ(tf.points(1).value(), 90);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 140);
  EXPECT_FLOAT_EQ(tf.points(1).opacity(), 0.5f);  // only values move
}

TEST(ApplyWindowLevel, WindowScalesAroundTheCentre) {
  v1::TransferFunction tf = ThreePoints();
  ApplyWindowLevel(tf, 0, 2);
  EXPECT_FLOAT_EQ(tf.points(0).value(), -50);
  EXPECT_FLOAT_EQ(tf.points(1).value(), 50);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 150);
  ApplyWindowLevel(tf, 10, 0.5f);
  EXPECT_FLOAT_EQ(tf.points(0).value(), 10);
  EXPECT_FLOAT_EQ(tf.points(1).value(), 60);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 110);
}

TEST(ApplyWindowLevel, ScaleClampedToItsRange) {
  v1::TransferFunction tf = ThreePoints();
  ApplyWindowLevel(tf, 0, 1000);  // clamped to 20
  EXPECT_FLOAT_EQ(tf.points(0).value(), 50 - 50 * 20);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 50 + 50 * 20);
  tf = ThreePoints();
  ApplyWindowLevel(tf, 0, 0.001f);  // clamped to 0.05
  EXPECT_FLOAT_EQ(tf.points(0).value(), 50 - 50 * 0.05f);
  EXPECT_FLOAT_EQ(tf.points(2).value(), 50 + 50 * 0.05f);
  ApplyWindowLevel(tf, 0, -3);  // not a scale: the window stays
  EXPECT_FLOAT_EQ(tf.points(0).value(), 50 - 50 * 0.05f);
}

TEST(ApplyWindowLevel, RepeatedNarrowingKeepsStrictOrder) {
  v1::TransferFunction tf = ThreePoints();
  for (int i = 0; i < 40; ++i) ApplyWindowLevel(tf, 0, 0.05f);
  ExpectStrictlyIncreasing(tf);
}

TEST(OpacityAt, InterpolatesLinearlyBetweenPoints) {
  const v1::TransferFunction tf = ThreePoints();
  EXPECT_FLOAT_EQ(OpacityAt(tf, 25), 0.25f);
  EXPECT_FLOAT_EQ(OpacityAt(tf, 50), 0.5f);
  EXPECT_FLOAT_EQ(OpacityAt(tf, 90), 0.9f);
}

TEST(OpacityAt, HoldsTheEndValuesBeyondTheEnds) {
  const v1::TransferFunction tf = ThreePoints();
  EXPECT_FLOAT_EQ(OpacityAt(tf, -1e6f), 0);
  EXPECT_FLOAT_EQ(OpacityAt(tf, 1e6f), 1);
  EXPECT_FLOAT_EQ(OpacityAt(v1::TransferFunction(), 3), 0);
}

TEST(DiffuseAt, InterpolatesAndHoldsBeyondTheEnds) {
  const v1::TransferFunction tf = ThreePoints();
  ExpectColor(DiffuseAt(tf, 75), 0, 0.5f, 0.5f);
  ExpectColor(DiffuseAt(tf, -5), 1, 0, 0);
  ExpectColor(DiffuseAt(tf, 500), 0, 0, 1);
  ExpectColor(DiffuseAt(v1::TransferFunction(), 3), 0, 0, 0);
}

}  // namespace
}  // namespace cinevol::viewer

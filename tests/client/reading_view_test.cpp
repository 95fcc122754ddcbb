// The viewer's reading tools: their words, and the client library's geometry
// under them: slice pixels and patient positions agree both ways,
// measurements have their textbook values, the 3D projection puts points
// where the server's own camera does, and the orientation marker follows the
// camera and the volume's direction cosines.
#include "viewer/reading_view.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/camera.h"

namespace cinevol::viewer {
namespace {

void ExpectNear(Vec3d a, Vec3d b, double tolerance = 1e-4) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tolerance) << "component " << i;
}

// An axial slice as the server sends it: the patient's right on the image's
// left (rows run to +x), anterior at the top (columns run to +y).
SliceGrid Axial() { return {{-10, -20, 30}, {1, 0, 0}, {0, 1, 0}, 0.5f, 0.75f, 40, 60}; }

const MarkerAxis& Find(const std::vector<MarkerAxis>& axes, char letter) {
  return *std::find_if(axes.begin(), axes.end(), [&](const MarkerAxis& a) { return a.letter == letter; });
}

TEST(ReadingView, PatientPositionsReadAsLetters) {
  EXPECT_EQ(PatientPosition({12, 3.5f, 40}), "L 12.0 P 3.5 S 40.0 mm");
  EXPECT_EQ(PatientPosition({-12, -3.54f, -0.04f}), "R 12.0 A 3.5 I 0.0 mm");
}

TEST(ReadingView, APickIsDescribedWithItsUnitAndLabel) {
  v1::PickResult pick;
  EXPECT_NE(DescribePick(pick, "HU").find("no hit"), std::string::npos);
  pick.set_hit(true);
  *pick.mutable_position_mm() = ToProto(Vec3d{1, -2, 3});
  pick.set_value(412.34f);
  EXPECT_EQ(DescribePick(pick, "HU"), "L 1.0 A 2.0 S 3.0 mm, value 412.3 HU");
  pick.mutable_label()->set_value(3);
  pick.mutable_label()->set_name("liver");
  EXPECT_EQ(DescribePick(pick, ""), "L 1.0 A 2.0 S 3.0 mm, value 412.3, label 3 liver");
}

TEST(ReadingView, SlicePixelsAndPatientPositionsAgreeBothWays) {
  const SliceGrid slice = Axial();
  ExpectNear(SlicePixelToPatient(slice, 0, 0), {-10, -20, 30});
  ExpectNear(SlicePixelToPatient(slice, 4, 2), {-8, -18.5, 30});
  const SlicePixel back = PatientToSlicePixel(slice, {-8, -18.5, 32});
  EXPECT_NEAR(back.column, 4, 1e-4f);
  EXPECT_NEAR(back.row, 2, 1e-4f);
  EXPECT_NEAR(back.off_plane_mm, 2, 1e-4f) << "rows x columns points to +z (superior)";
}

TEST(ReadingView, SliceGeometryComesFromTheImage) {
  v1::SliceImage image;
  *image.mutable_origin_mm() = ToProto(Vec3d{1, 2, 3});
  *image.mutable_row_direction() = ToProto(Vec3d{0, 1, 0});
  *image.mutable_column_direction() = ToProto(Vec3d{0, 0, -1});
  image.set_row_spacing_mm(2);
  image.set_column_spacing_mm(3);
  image.set_width(10);
  image.set_height(20);
  const SliceGrid g = SliceGrid::Of(image);
  ExpectNear(SlicePixelToPatient(g, 1, 1), {1, 4, 0});
  EXPECT_EQ(g.width, 10);
  EXPECT_EQ(g.height, 20);
}

TEST(ReadingView, DistancesAndAnglesHaveTheirTextbookValues) {
  EXPECT_DOUBLE_EQ(DistanceMm({0, 0, 0}, {3, 4, 0}), 5);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {0, 1, 0}), 90, 1e-4f);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {1, 1, 0}), 45, 1e-3f);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {2, 0, 0}), 0, 5e-2f) << "clamped: no NaN for parallel rays";
  v1::Measurement m;
  *m.add_points() = ToProto(Vec3d{0, 0, 0});
  *m.add_points() = ToProto(Vec3d{0, 42.5f, 0});
  EXPECT_EQ(MeasurementText(m), "42.5 mm");
  *m.add_points() = ToProto(Vec3d{10, 42.5f, 0});
  EXPECT_EQ(MeasurementText(m), "90.0 deg");
  *m.add_points() = ToProto(Vec3d{1, 1, 1});
  EXPECT_EQ(MeasurementText(m), "") << "four points measure nothing";
}

TEST(ReadingView, TheTargetProjectsToTheViewsCentreAndUpIsUp) {
  const ViewCamera camera{{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30};
  const auto centre = ProjectToView(camera, {0, 0, 0}, 200, 100);
  ASSERT_TRUE(centre);
  EXPECT_NEAR(centre->x, 100, 1e-3f);
  EXPECT_NEAR(centre->y, 50, 1e-3f);
  // A point at the top edge of the field of view: tan(15 deg) * 500 mm up.
  const auto top = ProjectToView(camera, {0, 0, 500 * std::tan(15 * M_PI / 180)}, 200, 100);
  ASSERT_TRUE(top);
  EXPECT_NEAR(top->y, 0, 1e-2f);
  const auto right = ProjectToView(camera, {10, 0, 0}, 200, 100);
  ASSERT_TRUE(right);
  EXPECT_GT(right->x, 100) << "looking along +y with z up, +x is on the right";
  EXPECT_FALSE(ProjectToView(camera, {0, -600, 0}, 200, 100)) << "behind the eye";
}

TEST(ReadingView, TheProjectionIsTheServersPinholeCamera) {
  const ViewCamera camera{{120, -300, 80}, {10, 5, -20}, {0.1, 0, 1}, 40};
  const auto f = [](Vec3d v) { return Vec3f{float(v.x), float(v.y), float(v.z)}; };
  const Camera server = LookAt(f(camera.eye), f(camera.target), f(camera.up), float(camera.fov_y_deg), 320, 200);
  for (const Vec3d p : {Vec3d{0, 0, 0}, Vec3d{40, -20, 60}, Vec3d{-70, 30, -10}}) {
    float px = 0, py = 0;
    ASSERT_TRUE(server.Project(f(p), px, py));
    const auto mine = ProjectToView(camera, p, 320, 200);
    ASSERT_TRUE(mine);
    EXPECT_NEAR(mine->x, px, 1e-2f);
    EXPECT_NEAR(mine->y, py, 1e-2f);
  }
}

TEST(ReadingView, TheMarkerShowsThePatientAxesAsTheCameraSeesThem) {
  // From the front (anterior view): the patient's left is on the viewer's
  // right, superior up, posterior away from the viewer.
  const ViewCamera front{{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30};
  const std::vector<MarkerAxis> axes = MarkerAxes(front, Placement{});
  ASSERT_EQ(axes.size(), 6u);
  EXPECT_NEAR(Find(axes, 'L').x, 1, 1e-5f);
  EXPECT_NEAR(Find(axes, 'S').y, 1, 1e-5f);
  EXPECT_NEAR(Find(axes, 'P').depth, -1, 1e-5f);
  EXPECT_EQ(axes.front().letter, 'P') << "farthest first";
  EXPECT_EQ(axes.back().letter, 'A');
  // A volume whose first index axis runs to the patient's right: the
  // volume-centred frame turns with it, so L is now on the viewer's left.
  const Placement flipped({-1, 0, 0, 0, 1, 0, 0, 0, 1}, {0, 0, 0}, {1, 1, 1}, {1, 1, 1});
  EXPECT_NEAR(Find(MarkerAxes(front, flipped), 'L').x, -1, 1e-5f);
}

TEST(ReadingView, CrosshairSlicesCrossTheirAxisAtTheCrosshair) {
  const Vec3d crosshair{1, 2, 3};
  EXPECT_FLOAT_EQ(CrosshairSlice("s", v1::AXIAL, crosshair).position_mm(), 3);
  EXPECT_FLOAT_EQ(CrosshairSlice("s", v1::CORONAL, crosshair).position_mm(), 2);
  const v1::SliceRequest sagittal = CrosshairSlice("s", v1::SAGITTAL, crosshair);
  EXPECT_FLOAT_EQ(sagittal.position_mm(), 1);
  EXPECT_EQ(sagittal.session_id(), "s");
  EXPECT_EQ(sagittal.axis(), v1::SAGITTAL);
}

TEST(ReadingView, IdentityFillsTheCornersPeopleExpect) {
  EXPECT_EQ(PersonName("Doe^John^^Dr"), "Doe, John Dr");
  EXPECT_EQ(PersonName("Yamada^Tarou=\x1b$B;3ED\x1b(B^\x1b$BB@O:\x1b(B"), "Yamada, Tarou");
  EXPECT_EQ(PersonName("ANONYMOUS"), "ANONYMOUS");
  EXPECT_EQ(StudyDate("20091203"), "2009-12-03");
  EXPECT_EQ(StudyDate("2009"), "2009");
  v1::PatientIdentity id;
  id.set_patient_name("My Patient Name");
  id.set_patient_id("123456789");
  id.set_study_date("20091203");
  id.set_series_description("T1 axial");
  const IdentityCorners corners = CornersOf(id);
  EXPECT_EQ(corners.top_left, (std::vector<std::string>{"My Patient Name", "ID 123456789"}));
  EXPECT_EQ(corners.top_right, (std::vector<std::string>{"2009-12-03", "T1 axial"}));  // no study description: no line
  EXPECT_TRUE(CornersOf(v1::PatientIdentity{}).empty());
}

TEST(ReadingView, ASlicePlanesOutlineIsWhereItCutsTheVolumesBox) {
  v1::VolumeInfo volume;  // 11 x 21 x 31 voxels of 1 x 1 x 2 mm, RAS-stored: index x runs to the patient's right
  volume.mutable_dims()->set_x(11);
  volume.mutable_dims()->set_y(21);
  volume.mutable_dims()->set_z(31);
  volume.mutable_spacing_mm()->set_x(1);
  volume.mutable_spacing_mm()->set_y(1);
  volume.mutable_spacing_mm()->set_z(2);
  for (double d : {-1, 0, 0, 0, -1, 0, 0, 0, 1}) volume.add_direction(d);
  const Placement placement = Placement::Of(volume);
  const std::vector<Vec3d> axial = placement.SlicePlaneOutline(2, 30);
  ASSERT_EQ(axial.size(), 4u);
  for (std::size_t i = 0; i < axial.size(); ++i) {
    EXPECT_FLOAT_EQ(axial[i].z, 30);
    EXPECT_GE(axial[i].x, -10.001f);
    EXPECT_LE(axial[i].x, 0.001f);
    const Vec3d& next = axial[(i + 1) % axial.size()];  // neighbours share a side: no diagonal
    EXPECT_TRUE(std::fabs(axial[i].x - next.x) < 1e-4f || std::fabs(axial[i].y - next.y) < 1e-4f) << i;
  }
  EXPECT_EQ(placement.SlicePlaneOutline(0, 1).size(), 0u) << "beyond the box: nothing";
  EXPECT_EQ(placement.SlicePlaneOutline(0, -5).size(), 4u);
}

TEST(ReadingView, AVoxelStepFollowsTheIndexAxisAlongThePatientAxis) {
  v1::VolumeInfo volume;
  *volume.mutable_spacing_mm() = ToProto(Vec3d{0.5, 0.7, 2.5});
  EXPECT_FLOAT_EQ(Placement::Of(volume).VoxelStepMm(2), 2.5f);
  // Index axis 2 runs along y and axis 1 along z (a coronal acquisition).
  for (double d : {1, 0, 0, 0, 0, 1, 0, 1, 0}) volume.add_direction(d);
  EXPECT_FLOAT_EQ(Placement::Of(volume).VoxelStepMm(2), 0.7f);
  EXPECT_FLOAT_EQ(Placement::Of(volume).VoxelStepMm(1), 2.5f);
}

}  // namespace
}  // namespace cinevol::viewer

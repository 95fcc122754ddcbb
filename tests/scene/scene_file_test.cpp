// Scene JSON: examples load, round trips are exact, defaults are filled and
// every validation rule rejects with a message naming its field.
#include "scene/scene_file.h"

#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>

#include "core/error.h"
#include "scene/presets.h"
#include "scene/scene_fields.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

namespace fs = std::filesystem;
using testing::ScratchDir;

constexpr float kFloatMax = std::numeric_limits<float>::max();

fs::path Examples() { return fs::path(CINEVOL_SOURCE_DIR) / "examples"; }

TEST(SceneFile, EveryExampleLoads) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(Examples())) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(LoadSceneFile(entry.path()));
    ++count;
  }
  EXPECT_GE(count, 3);
}

TEST(SceneFile, JsonRoundTripIsExact) {
  for (const char* name : {"ct-bone.json", "ct-soft-tissue.json", "mr-head.json"}) {
    const v1::Scene scene = LoadSceneFile(Examples() / name);
    const v1::Scene again = ParseSceneJson(SceneToJson(scene));
    EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(scene, again)) << name;
  }
}

TEST(SceneFile, SaveThenLoadKeepsTheScene) {
  ScratchDir dir;
  const v1::Scene scene = LoadSceneFile(Examples() / "ct-soft-tissue.json");
  SaveSceneFile(scene, dir / "copy.json");
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(scene, LoadSceneFile(dir / "copy.json")));
}

TEST(SceneFile, MeasurementsAreKeptAndChecked) {
  ScratchDir dir;
  v1::Scene scene = LoadSceneFile(Examples() / "ct-soft-tissue.json");
  v1::Measurement* distance = scene.add_measurements();
  distance->set_name("tumour long axis");
  for (float x : {10.0f, 52.5f}) {
    v1::Vec3* p = distance->add_points();
    p->set_x(x);
    p->set_y(-3);
  }
  SaveSceneFile(scene, dir / "measured.json");
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(scene, LoadSceneFile(dir / "measured.json")));

  distance->mutable_points(0)->set_z(std::numeric_limits<float>::quiet_NaN());
  distance->add_points();
  distance->add_points();
  scene.add_measurements()->set_name(std::string(kMaxMeasurementName + 1, 'x'));
  const std::vector<std::string> problems = ValidateScene(scene);
  const auto names = [&](const std::string& text) {
    return std::any_of(problems.begin(), problems.end(), [&](const std::string& p) { return p.find(text) == 0; });
  };
  EXPECT_TRUE(names("measurements[0].points[0].z")) << ::testing::PrintToString(problems);
  EXPECT_TRUE(names("measurements[0].points: 4 points")) << ::testing::PrintToString(problems);
  EXPECT_TRUE(names("measurements[1].name")) << ::testing::PrintToString(problems);
  for (int i = 0; i < kMaxMeasurements; ++i) scene.add_measurements();
  EXPECT_TRUE(names("measurements")) << ::testing::PrintToString(problems);
  EXPECT_EQ(ValidateScene(scene).front().rfind("measurements: ", 0), 0u);
}

// A scene for a volume named elsewhere (`cinevol snapshot --volume ID --scene F`, a presentation state's) names none.
TEST(SceneFile, ASceneForAVolumeNamedElsewhereNamesNone) {
  const v1::Scene scene = ParseSceneJson(R"({"transferFunction": {"preset": "ct-bone"}})");
  EXPECT_EQ(scene.volume().source_case(), v1::VolumeSource::SOURCE_NOT_SET);
}

TEST(SceneFile, DefaultsAreFilled) {
  const v1::Scene s = ParseSceneJson(R"({"volume": {"phantom": {"kind": "CUBE"}},
                                         "transferFunction": {"points": [{"value": 0, "opacity": 1}]}})");
  EXPECT_EQ(s.render().width(), 640u);
  EXPECT_EQ(s.render().height(), 480u);
  EXPECT_EQ(s.render().spp(), 2u);
  EXPECT_EQ(s.render().max_bounces(), 4u);
  EXPECT_EQ(s.camera().fov_y_deg(), 30.0f);
  EXPECT_EQ(s.camera().view(), v1::ANTERIOR);
  EXPECT_EQ(s.transfer_function().density_scale(), 1.0f);
  EXPECT_EQ(s.transfer_function().gradient_factor(), 1.0f);
  // With a preset, density and gradient factor are the preset's own.
  const v1::Scene p = ParseSceneJson(R"({"volume": {"phantom": {"kind": "CUBE"}},
                                         "transferFunction": {"preset": "ct-bone"}})");
  EXPECT_FALSE(p.transfer_function().has_density_scale());
}

TEST(SceneFile, RelativePathsResolveAgainstTheSceneFolder) {
  ScratchDir dir;
  fs::create_directories(dir / "scenes");
  std::ofstream(dir / "scenes/s.json") << R"({"volume": {"file": "../data/head.nii.gz"},
                                              "transferFunction": {"preset": "ct-bone"}})";
  const v1::Scene s = LoadSceneFile(dir / "scenes/s.json");
  EXPECT_EQ(fs::path(s.volume().file()), (dir / "data/head.nii.gz").lexically_normal());
}

TEST(SceneFile, UnknownFieldsAndBadJsonAreRejected) {
  EXPECT_THROW(ParseSceneJson(R"({"volume": {"phantom": {"kind": "HEAD"}}, "colour": 1})"), InputError);
  EXPECT_THROW(ParseSceneJson("{ not json"), InputError);
  try {
    LoadSceneFile("/nonexistent/scene.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.json"), std::string::npos);
  }
}

// A valid scene to break one field at a time.
v1::Scene ValidScene() { return LoadSceneFile(Examples() / "ct-soft-tissue.json"); }

struct Rule {
  const char* name;
  std::function<void(v1::Scene&)> breaks;
  const char* field;  // must appear in the error
};

void PrintTo(const Rule& r, std::ostream* os) { *os << r.name; }

class ValidationRule : public ::testing::TestWithParam<Rule> {};

TEST_P(ValidationRule, RejectsNamingTheField) {
  v1::Scene scene = ValidScene();
  ASSERT_TRUE(ValidateScene(scene).empty());
  GetParam().breaks(scene);
  const auto problems = ValidateScene(scene);
  ASSERT_FALSE(problems.empty()) << "not rejected";
  bool named = false;
  for (const auto& p : problems) named |= p.find(GetParam().field) != std::string::npos;
  EXPECT_TRUE(named) << "no problem names " << GetParam().field << "; got: " << problems[0];
  EXPECT_THROW(CheckScene(scene), InputError);
}

v1::AreaLight* Area(v1::Scene& s) { return s.mutable_lights(0)->mutable_area(); }
v1::TransferFunctionPoint* Point(v1::Scene& s, int i) { return s.mutable_transfer_function()->mutable_points(i); }

INSTANTIATE_TEST_SUITE_P(
    SceneFile, ValidationRule,
    ::testing::Values(
        Rule{"NaNEye", [](v1::Scene& s) { s.mutable_camera()->mutable_eye()->set_x(NAN); }, "camera.eye.x"},
        Rule{"InfTarget", [](v1::Scene& s) { s.mutable_camera()->mutable_target()->set_z(INFINITY); },
             "camera.target.z"},
        Rule{"EyeEqualsTarget", [](v1::Scene& s) { *s.mutable_camera()->mutable_target() = s.camera().eye(); },
             "camera.target"},
        Rule{"ZeroUp", [](v1::Scene& s) { s.mutable_camera()->mutable_up()->Clear(); }, "camera.up"},
        Rule{"UpAlongView", [](v1::Scene& s) {
               auto* c = s.mutable_camera();
               c->mutable_up()->set_x(c->target().x() - c->eye().x());
               c->mutable_up()->set_y(c->target().y() - c->eye().y());
               c->mutable_up()->set_z(c->target().z() - c->eye().z());
             }, "camera.up"},
        Rule{"FovTooWide", [](v1::Scene& s) { s.mutable_camera()->set_fov_y_deg(180); }, "camera.fovYDeg"},
        Rule{"NegativeAperture", [](v1::Scene& s) { s.mutable_camera()->set_aperture_mm(-1); }, "camera.apertureMm"},
        Rule{"ZeroAreaLight", [](v1::Scene& s) { *Area(s)->mutable_edge_v() = Area(s)->edge_u(); }, "lights[0].area"},
        Rule{"NegativeLightIntensity", [](v1::Scene& s) { Area(s)->set_intensity(-2); }, "lights[0].area.intensity"},
        Rule{"NegativeLightColor", [](v1::Scene& s) { Area(s)->mutable_color()->set_g(-1); }, "lights[0].area.color.g"},
        Rule{"ZeroDirection", [](v1::Scene& s) { s.add_lights()->mutable_directional(); },
             "lights[2].directional.direction"},
        Rule{"TwoEnvironments", [](v1::Scene& s) { *s.add_lights() = s.lights(1); }, "lights[2].environment"},
        Rule{"LightWithoutKind", [](v1::Scene& s) { s.add_lights(); }, "lights[2]"},
        Rule{"UnsortedPoints", [](v1::Scene& s) { Point(s, 2)->set_value(-200); }, "transferFunction.points[2].value"},
        Rule{"DuplicatePointValue", [](v1::Scene& s) { Point(s, 3)->set_value(Point(s, 2)->value()); },
             "transferFunction.points[3].value"},
        Rule{"OpacityAboveOne", [](v1::Scene& s) { Point(s, 1)->set_opacity(1.5f); },
             "transferFunction.points[1].opacity"},
        Rule{"NegativeDiffuse", [](v1::Scene& s) { Point(s, 0)->mutable_diffuse()->set_r(-0.1f); },
             "transferFunction.points[0].diffuse.r"},
        Rule{"RoughnessNaN", [](v1::Scene& s) { Point(s, 0)->set_roughness(NAN); },
             "transferFunction.points[0].roughness"},
        Rule{"NegativeEmission", [](v1::Scene& s) { Point(s, 4)->mutable_emission()->set_b(-1); },
             "transferFunction.points[4].emission.b"},
        Rule{"UnknownPreset", [](v1::Scene& s) {
               s.mutable_transfer_function()->clear_points();
               s.mutable_transfer_function()->set_preset("ct-teapot");
             }, "transferFunction.preset"},
        Rule{"NegativeDensity", [](v1::Scene& s) { s.mutable_transfer_function()->set_density_scale(-1); },
             "transferFunction.densityScale"},
        Rule{"NegativeGradientFactor", [](v1::Scene& s) { s.mutable_transfer_function()->set_gradient_factor(-1); },
             "transferFunction.gradientFactor"},
        Rule{"PhaseGOne", [](v1::Scene& s) { s.mutable_transfer_function()->set_phase_g(1); },
             "transferFunction.phaseG"},
        Rule{"ZeroWidth", [](v1::Scene& s) { s.mutable_render()->set_width(0); }, "render.width"},
        Rule{"HugeHeight", [](v1::Scene& s) { s.mutable_render()->set_height(100000); }, "render.height"},
        Rule{"ZeroSpp", [](v1::Scene& s) { s.mutable_render()->set_spp(0); }, "render.spp"},
        Rule{"TooManyBounces", [](v1::Scene& s) { s.mutable_render()->set_max_bounces(100000); }, "render.maxBounces"},
        Rule{"LabelsOfNoVolume",
             [](v1::Scene& s) {
               s.clear_volume();
               s.mutable_volume()->set_labels("seg.nii.gz");
             }, "volume"},
        Rule{"NegativePhantomSize", [](v1::Scene& s) { s.mutable_volume()->mutable_phantom()->set_spacing(-1); },
             "volume.phantom"},
        Rule{"ZeroCropSize", [](v1::Scene& s) { s.mutable_clipping()->mutable_crop_box()->mutable_size()->set_x(1); },
             "clipping.cropBox.size.y"},
        Rule{"NaNCropCenter",
             [](v1::Scene& s) { s.mutable_clipping()->mutable_crop_box()->mutable_center()->set_z(NAN); },
             "clipping.cropBox.center.z"},
        Rule{"ParallelCropAxes", [](v1::Scene& s) {
               auto* b = s.mutable_clipping()->mutable_crop_box();
               b->mutable_size()->set_x(1), b->mutable_size()->set_y(1), b->mutable_size()->set_z(1);
               b->mutable_axis_x()->set_x(1), b->mutable_axis_y()->set_x(2);
             }, "clipping.cropBox"},
        Rule{"ZeroPlaneNormal", [](v1::Scene& s) { s.mutable_clipping()->add_planes(); }, "clipping.planes[0].normal"},
        Rule{"TinyPlaneNormal",
             [](v1::Scene& s) { s.mutable_clipping()->add_planes()->mutable_normal()->set_y(1e-30f); },
             "clipping.planes[0].normal"},
        Rule{"SevenPlanes", [](v1::Scene& s) {
               for (int i = 0; i < 7; ++i) s.mutable_clipping()->add_planes()->mutable_normal()->set_z(1);
             }, "clipping.planes"},
        Rule{"UnknownReconstruction",
             [](v1::Scene& s) { s.mutable_render()->set_reconstruction(v1::Reconstruction(9)); },
             "render.reconstruction"},
        Rule{"LabelOutOfRange", [](v1::Scene& s) { s.mutable_labels()->add_styles()->set_value(70000); },
             "labels.styles[0].value"},
        Rule{"LabelStyledTwice", [](v1::Scene& s) {
               s.mutable_labels()->add_styles()->set_value(5);
               s.mutable_labels()->add_styles()->set_value(5);
             }, "labels.styles[1].value"},
        Rule{"LabelOpacityScaleNegative", [](v1::Scene& s) { s.mutable_labels()->add_styles()->set_opacity_scale(-1); },
             "labels.styles[0].opacityScale"},
        Rule{"LabelColourOver1", [](v1::Scene& s) { s.mutable_labels()->add_styles()->mutable_color()->set_g(2); },
             "labels.styles[0].color"},
        Rule{"LabelTransferFunctionUnsorted", [](v1::Scene& s) {
               auto* tf = s.mutable_labels()->add_styles()->mutable_transfer_function();
               tf->add_points()->set_value(10);
               tf->add_points()->set_value(5);
             }, "labels.styles[0].transferFunction.points[1].value"},
        Rule{"NineLabelTransferFunctions", [](v1::Scene& s) {
               for (int i = 0; i < 9; ++i) {
                 auto* style = s.mutable_labels()->add_styles();
                 style->set_value(i);
                 style->mutable_transfer_function()->set_preset("ct-bone");
               }
             }, "labels.styles"},
        Rule{"LabelTableWithoutLabels", [](v1::Scene& s) { s.mutable_volume()->set_label_table("names.tsv"); },
             "volume.labelTable"},
        // At the extremes (docs/rendering.md, "Values at the extremes").
        Rule{"OpacityFloatMax", [](v1::Scene& s) { Point(s, 1)->set_opacity(kFloatMax); },
             "transferFunction.points[1].opacity"},
        Rule{"OpacityMinusFloatMax", [](v1::Scene& s) { Point(s, 1)->set_opacity(-kFloatMax); },
             "transferFunction.points[1].opacity"},
        Rule{"PointValueNaN", [](v1::Scene& s) { Point(s, 3)->set_value(NAN); }, "transferFunction.points[3].value"},
        Rule{"PointValueInfinite", [](v1::Scene& s) { Point(s, 5)->set_value(INFINITY); },
             "transferFunction.points[5].value"},
        Rule{"EmissionFloatMax", [](v1::Scene& s) { Point(s, 4)->mutable_emission()->set_r(kFloatMax); },
             "transferFunction.points[4].emission.r"},
        Rule{"DensityFloatMax", [](v1::Scene& s) { s.mutable_transfer_function()->set_density_scale(kFloatMax); },
             "transferFunction.densityScale"},
        Rule{"DensityNaN", [](v1::Scene& s) { s.mutable_transfer_function()->set_density_scale(NAN); },
             "transferFunction.densityScale"},
        Rule{"GradientFactorInfinite",
             [](v1::Scene& s) { s.mutable_transfer_function()->set_gradient_factor(INFINITY); },
             "transferFunction.gradientFactor"},
        Rule{"LightIntensityFloatMax", [](v1::Scene& s) { Area(s)->set_intensity(kFloatMax); },
             "lights[0].area.intensity"},
        Rule{"LightColourTimesIntensityTooBright", [](v1::Scene& s) {
               Area(s)->mutable_color()->set_r(1e7f);
               Area(s)->set_intensity(1e7f);
             }, "lights[0].area.intensity"},
        Rule{"LightColourFloatMax", [](v1::Scene& s) { Area(s)->mutable_color()->set_b(kFloatMax); },
             "lights[0].area.intensity"},
        Rule{"PointLightAtFloatMax", [](v1::Scene& s) {
               auto* point = s.add_lights()->mutable_point();
               point->mutable_position()->set_x(kFloatMax);
               point->set_intensity(1);
             }, "lights[2].point.position.x"},
        Rule{"TinyLightDirection", [](v1::Scene& s) {
               s.add_lights()->mutable_directional()->mutable_direction()->set_z(1e-30f);
             }, "lights[2].directional.direction"},
        Rule{"TinyAreaLight", [](v1::Scene& s) {
               v1::Vec3* u = Area(s)->mutable_edge_u();
               u->set_x(1e-20f), u->set_y(0), u->set_z(0);
             }, "lights[0].area"},
        Rule{"SkyFloatMax", [](v1::Scene& s) {
               s.mutable_lights(1)->mutable_environment()->mutable_uniform()->set_g(kFloatMax);
             }, "lights[1].environment.uniform"},
        Rule{"SkyIntensityFloatMax",
             [](v1::Scene& s) { s.mutable_lights(1)->mutable_environment()->set_intensity(kFloatMax); },
             "lights[1].environment.intensity"},
        Rule{"EyeAt1e30", [](v1::Scene& s) { s.mutable_camera()->mutable_eye()->set_y(-1e30f); }, "camera.eye.y"},
        Rule{"TargetAtFloatMax", [](v1::Scene& s) { s.mutable_camera()->mutable_target()->set_x(kFloatMax); },
             "camera.target.x"},
        Rule{"TinyUp", [](v1::Scene& s) {
               v1::Vec3* up = s.mutable_camera()->mutable_up();
               up->set_x(1e-30f), up->set_z(0);
             }, "camera.up"},
        Rule{"ApertureFloatMax", [](v1::Scene& s) { s.mutable_camera()->set_aperture_mm(kFloatMax); },
             "camera.apertureMm"},
        Rule{"FocalDistanceFloatMax", [](v1::Scene& s) { s.mutable_camera()->set_focal_distance_mm(kFloatMax); },
             "camera.focalDistanceMm"},
        Rule{"ClipPlaneFarAway", [](v1::Scene& s) {
               auto* plane = s.mutable_clipping()->add_planes();
               plane->mutable_normal()->set_z(1);
               plane->mutable_point()->set_z(-kFloatMax);
             }, "clipping.planes[0].point.z"}),
    [](const auto& info) { return std::string(info.param.name); });

// What validation leaves through at the extremes is what the renderer
// takes: the largest accepted values load.
TEST(SceneFile, AcceptsTheLargestValuesItAllows) {
  v1::Scene scene = ValidScene();
  Point(scene, 0)->set_value(-kFloatMax);  // points anywhere float reaches
  Point(scene, 5)->set_value(kFloatMax);
  Point(scene, 4)->mutable_emission()->set_g(kMaxRadiance);
  scene.mutable_transfer_function()->set_density_scale(1e6f);
  scene.mutable_transfer_function()->set_gradient_factor(kFloatMax);
  Area(scene)->set_intensity(kMaxRadiance);
  scene.mutable_camera()->mutable_eye()->set_x(-kMaxSceneMm);
  scene.mutable_lights(1)->mutable_environment()->set_rotation_deg(kFloatMax);
  EXPECT_TRUE(ValidateScene(scene).empty()) << ValidateScene(scene)[0];
}

// One table says each number's default and range (scene_fields.h); the docs
// show that table, so they cannot drift from what validation does.
TEST(SceneFields, TheDocsShowTheTableValidationUses) {
  std::ifstream in(fs::path(CINEVOL_SOURCE_DIR) / "docs" / "api.md");
  const std::string docs((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string table = SceneNumbersMarkdown();
  EXPECT_NE(docs.find(table), std::string::npos) << "docs/api.md should hold this table:\n" << table;
}

TEST(SceneFields, EveryBoundIsEnforcedAndEveryDefaultFilled) {
  for (const NumberField<v1::Camera>& f : CameraNumbers()) {
    SCOPED_TRACE(std::string(f.name));
    v1::Scene scene = ValidScene();
    f.set(*scene.mutable_camera(), f.hi * 2 + 1);
    ASSERT_FALSE(ValidateScene(scene).empty());
    EXPECT_NE(ValidateScene(scene)[0].find("camera." + std::string(f.name)), std::string::npos);
    f.set(*scene.mutable_camera(), f.lo);
    EXPECT_TRUE(ValidateScene(scene).empty());
  }
  v1::Scene scene = ValidScene();
  scene.clear_render();
  scene.mutable_transfer_function()->clear_phase_g();
  ApplyDefaults(scene, kEverythingChanged);
  for (const NumberField<v1::RenderSettings>& f : RenderNumbers()) EXPECT_EQ(f.get(scene.render()), *f.fallback);
  EXPECT_EQ(scene.transfer_function().phase_g(), 0.0f);
}

TEST(Presets, EveryPresetIsAValidTransferFunction) {
  for (const std::string& name : PresetNames()) {
    v1::Scene scene = ValidScene();
    *scene.mutable_transfer_function() = MakePreset(name, ValueWindow{-1024, 3071});
    EXPECT_TRUE(ValidateScene(scene).empty()) << name;
  }
}

TEST(Presets, CtPresetsAreInHounsfieldUnits) {
  const auto bone = MakePreset("ct-bone", ValueWindow{0, 1});  // the window must not matter
  EXPECT_GE(bone.points(0).value(), 0.0f);
  EXPECT_GE(bone.points(bone.points_size() - 1).value(), 1000.0f);
  const auto lung = MakePreset("ct-lung", ValueWindow{0, 1});
  EXPECT_LE(lung.points(0).value(), -700.0f);  // its band lies between air and tissue, in HU
}

TEST(Presets, WindowPresetsFollowTheWindow) {
  const auto a = MakePreset("mr-default", ValueWindow{0, 100}), b = MakePreset("mr-default", ValueWindow{0, 1000});
  EXPECT_NEAR(b.points(1).value(), 10 * a.points(1).value(), 1e-3);
  const auto flat = MakePreset("mr-default", ValueWindow{5, 5});  // constant volume: still sorted
  for (int i = 1; i < flat.points_size(); ++i) EXPECT_GT(flat.points(i).value(), flat.points(i - 1).value());
  EXPECT_THROW(MakePreset("ct-teapot", ValueWindow{}), InputError);
}

}  // namespace
}  // namespace cinevol

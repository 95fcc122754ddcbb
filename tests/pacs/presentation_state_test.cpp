// Volume Rendering Volumetric Presentation States (pacs/presentation_state.h, runtime/presentation_store.h; issue
// 57): every part read back as written; the object checked against PS3.3's module tables (Debian's dciodvfy knows
// the attributes but not this IOD, so it checks values and VRs only, and the tables are checked here); one another
// system wrote (no recipe) read from the standard's attributes alone; the standard's attributes winning over the
// recipe where they differ; hostile objects and every truncation refused by name, never a crash.
#include "pacs/presentation_state.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"
#include "pacs/dicom_json.h"
#include "pacs/part10_reader.h"
#include "runtime/presentation_store.h"
#include "scene/scene_file.h"
#include "support/error_of.h"
#include "support/shell_command.h"
#include "support/test_paths.h"

namespace cinevol::pacs {
namespace {

namespace fs = std::filesystem;
using namespace cinevol::testing;

constexpr const char* kFrame = "2.25.3400571";
constexpr const char* kCtImage = "1.2.840.10008.5.1.4.1.1.2";

SourceStudy Study() {
  SourceStudy study;
  study.patient_name = "Cinevol^Presented";
  study.patient_id = "CINEVOL-PR-1";
  study.patient_birth_date = "19700101";
  study.patient_sex = "O";
  study.study_uid = "2.25.3400572";
  study.study_id = "PR1";
  study.study_date = "20240102";
  study.study_time = "093000";
  study.accession_number = "ACC-PR-1";
  study.referring_physician = "Ref^Erring";
  study.study_description = "Chest CT";
  study.series_uid = "2.25.3400572.1";
  return study;
}

ReportSource Source() {
  ReportSource source;
  source.frame_of_reference_uid = kFrame;
  for (int i = 1; i <= 3; ++i) source.images.push_back({kCtImage, "2.25.3400572.1." + std::to_string(i)});
  return source;
}

// A scene as a session stores one: patient coordinates, transfer-function points, a crop box along the volume's
// axes and a clip plane with a cap, a key light and materials the IOD has no place for.
v1::Scene Scene() {
  return ParseSceneJson(R"({
    "frame": "PATIENT_LPS",
    "transferFunction": {"preset": "ct-bone", "densityScale": 3, "points": [
      {"value": -200, "opacity": 0, "diffuse": {"r": 0.9, "g": 0.8, "b": 0.7}, "roughness": 0.4},
      {"value": 300, "opacity": 0.8, "diffuse": {"r": 1, "g": 0.95, "b": 0.9}, "roughness": 0.2},
      {"value": 1500, "opacity": 1, "diffuse": {"r": 1, "g": 1, "b": 1}, "specular": {"r": 0.1, "g": 0.1, "b": 0.1}}]},
    "camera": {"eye": {"x": 10, "y": -600, "z": 40}, "target": {"x": 5, "y": -120, "z": 30},
               "up": {"x": 0, "y": 0, "z": 1}, "fovYDeg": 28, "exposure": 0.5},
    "lights": [{"point": {"position": {"x": 300, "y": -500, "z": 400}, "color": {"r": 1, "g": 1, "b": 1},
                          "intensity": 2e6}}],
    "render": {"width": 320, "height": 240, "spp": 64, "seed": 9},
    "clipping": {"cropBox": {"center": {"x": 0, "y": -150, "z": -20}, "size": {"x": 250, "y": 200, "z": 400},
                             "cap": true},
                 "planes": [{"point": {"x": 30, "y": 0, "z": 0}, "normal": {"x": -1, "y": 0, "z": 0}, "cap": true}]}
  })");
}

Volume TestVolume() {
  VolumeMetadata metadata;
  return Volume({64, 64, 32}, {0.7f, 0.7f, 2.5f}, std::vector<float>(64 * 64 * 32, 0.0f), metadata);
}

PresentationState State(const v1::Scene& scene = Scene()) {
  PresentationState state = service::PresentationOf(scene, TestVolume());
  state.rendered_sop_class_uid = kSecondaryCaptureSopClass;
  state.rendered_sop_instance_uid = "2.25.3400573.1";
  state.rendered_series_uid = "2.25.3400573";
  return state;
}

constexpr std::array<double, 6> kAxialAxes{1, 0, 0, 0, 1, 0};

TEST(PresentationState, EveryPartReadsBackAsWritten) {
  const PresentationState state = State();
  PresentationStateUids uids;
  const ReadPresentation read = ReadPresentationState(MakePresentationState(Study(), Source(), state, "0.9.0", &uids));
  EXPECT_EQ(read.uids.sop_instance_uid, uids.sop_instance_uid);
  EXPECT_EQ(read.uids.study_uid, Study().study_uid);
  EXPECT_EQ(read.frame_of_reference_uid, kFrame);
  EXPECT_EQ(read.source_study_uid, Study().study_uid);
  EXPECT_EQ(read.source_series_uid, Study().series_uid);
  EXPECT_EQ(read.input_images.size(), 3u);
  EXPECT_EQ(read.state.geometry.viewpoint, state.geometry.viewpoint);  // FD: to the bit
  EXPECT_EQ(read.state.geometry.field_of_view, state.geometry.field_of_view);
  ASSERT_TRUE(read.state.cropping.bounding_box);
  EXPECT_EQ(*read.state.cropping.bounding_box, *state.cropping.bounding_box);
  ASSERT_EQ(read.state.cropping.plane_sets.size(), 1u);
  EXPECT_EQ(read.state.cropping.plane_sets[0][0].plane, state.cropping.plane_sets[0][0].plane);
  EXPECT_EQ(read.state.classification.rgba, state.classification.rgba);
  EXPECT_EQ(read.state.classification.window_center, 650);
  EXPECT_EQ(read.state.classification.window_width, 1700);
  EXPECT_EQ(read.state.classification.description, "ct-bone");
  EXPECT_EQ(read.state.label, "CINEVOL_RENDER");
  EXPECT_EQ(read.state.description, "cinevol render: ct-bone");
  EXPECT_EQ(read.state.rendered_sop_instance_uid, "2.25.3400573.1");
  EXPECT_EQ(read.state.rendered_series_uid, "2.25.3400573");
  EXPECT_EQ(read.state.recipe_json, state.recipe_json);

  // And as a scene: the one it was made from.
  const v1::Scene scene = service::SceneOf(read, kAxialAxes);
  v1::Scene expected = Scene();
  expected.clear_volume();
  expected.mutable_camera()->set_fov_y_deg(scene.camera().fov_y_deg());  // through tan and atan
  EXPECT_NEAR(scene.camera().fov_y_deg(), 28, 1e-4);
  EXPECT_EQ(SceneToJson(scene), SceneToJson(expected));
}

// The standard's attributes without cinevol's recipe, as another system writes them: the view, the crop, the colours
// and opacities all come through (the transfer function as 256 points of the palette).
TEST(PresentationState, AStateWithoutARecipeIsReadFromTheStandardsAttributes) {
  PresentationState state = State();
  state.recipe_json.clear();
  const v1::Scene scene =
      service::SceneOf(ReadPresentationState(MakePresentationState(Study(), Source(), state, "0.9.0")), kAxialAxes);
  EXPECT_FLOAT_EQ(scene.camera().eye().y(), -600);
  EXPECT_FLOAT_EQ(scene.camera().target().x(), 5);
  EXPECT_NEAR(scene.camera().fov_y_deg(), 28, 1e-4);
  EXPECT_EQ(scene.render().width() * 3, scene.render().height() * 4);  // the aspect of the field of view
  EXPECT_EQ(scene.lights_size(), 0);                                   // the session's default lights
  ASSERT_TRUE(scene.clipping().has_crop_box());
  EXPECT_NEAR(scene.clipping().crop_box().size().x(), 250, 1e-3);
  EXPECT_NEAR(scene.clipping().crop_box().center().y(), -150, 1e-3);
  EXPECT_FALSE(scene.clipping().crop_box().cap());  // a cap is cinevol's own
  ASSERT_EQ(scene.clipping().planes_size(), 1);
  EXPECT_FLOAT_EQ(scene.clipping().planes(0).normal().x(), -1);
  EXPECT_FLOAT_EQ(scene.clipping().planes(0).point().x(), 30);
  const v1::TransferFunction& tf = scene.transfer_function();
  ASSERT_EQ(tf.points_size(), 256);
  EXPECT_FLOAT_EQ(tf.points(0).value(), -200);
  EXPECT_FLOAT_EQ(tf.points(255).value(), 1500);
  EXPECT_NEAR(tf.points(255).opacity(), 1, 1e-4);
  EXPECT_NEAR(tf.density_scale(), 3, 3e-3);  // the densest extinction, through alpha over the sampling step
  EXPECT_NEAR(tf.points(0).diffuse().r(), 0.9, 1e-4);
  EXPECT_NEAR(tf.points(0).specular().r(), 0.1 / 3, 1e-4);  // the shading's: the points' mean specular
  EXPECT_NEAR(tf.points(0).roughness(), (0.4 + 0.2 + 0) / 3, 1e-4);
  EXPECT_EQ(tf.preset(), "ct-bone");
  v1::Scene with_defaults = scene;  // as a session takes it
  ApplyDefaults(with_defaults);
  const std::vector<std::string> problems = ValidateSceneParts(with_defaults);
  EXPECT_TRUE(problems.empty()) << fmt::format("{}", fmt::join(problems, "\n"));
}

// A state another viewer edited keeps cinevol's recipe but changes the standard's attributes: the edit shows.
TEST(PresentationState, TheStandardsAttributesWinOverTheRecipe) {
  PresentationState state = State();
  state.geometry.viewpoint = {0, -900, 0};
  for (auto& entry : state.classification.rgba) entry[3] = entry[3] / 2;  // half as opaque
  state.cropping.bounding_box.reset();
  const v1::Scene scene =
      service::SceneOf(ReadPresentationState(MakePresentationState(Study(), Source(), state, "0.9.0")), kAxialAxes);
  EXPECT_FLOAT_EQ(scene.camera().eye().y(), -900);
  EXPECT_FLOAT_EQ(scene.camera().exposure(), 0.5f);  // what the IOD cannot say stays the recipe's
  EXPECT_EQ(scene.lights_size(), 1);
  const v1::TransferFunction& tf = scene.transfer_function();
  EXPECT_EQ(tf.points_size(), 256);  // the palette's: the edited opacities
  const double edited = -std::log(1 - state.classification.rgba.back()[3] / 65535.0) /
                        state.classification.sampling_step_mm;
  EXPECT_NEAR(tf.points(255).opacity() * tf.density_scale(), edited, 1e-3 * edited);
  EXPECT_LT(tf.density_scale(), 2);  // half the alpha: less than the recipe's 3
  EXPECT_FALSE(scene.clipping().has_crop_box());
  EXPECT_TRUE(scene.clipping().planes(0).cap());  // the same plane: the recipe's cap
}

// A crop box not along the volume's axes is six planes, and the recipe's box again where they are its faces.
TEST(PresentationState, AnObliqueCropBoxIsSixPlanesAndComesBackAsTheBox) {
  v1::Scene scene = Scene();
  v1::CropBox& box = *scene.mutable_clipping()->mutable_crop_box();
  box.mutable_axis_x()->set_x(0.8f);
  box.mutable_axis_x()->set_y(0.6f);
  box.mutable_axis_y()->set_x(-0.6f);
  box.mutable_axis_y()->set_y(0.8f);
  const PresentationState state = State(scene);
  EXPECT_FALSE(state.cropping.bounding_box);
  ASSERT_EQ(state.cropping.plane_sets.size(), 2u);
  EXPECT_EQ(state.cropping.plane_sets[0].size(), 6u);
  const v1::Scene read =
      service::SceneOf(ReadPresentationState(MakePresentationState(Study(), Source(), state, "0.9.0")), kAxialAxes);
  EXPECT_EQ(read.clipping().crop_box().DebugString(), box.DebugString());
  EXPECT_EQ(read.clipping().planes_size(), 1);
}

// Type 1 attributes present with a value, Type 2 present, by PS3.3's tables for this IOD (A.80.2) and its modules;
// and the Volume Rendering class's own constraints (PS3.4 B.5.1.24).
std::vector<std::string> ConformanceProblems(const std::string& bytes) {
  const Part10Dataset d = Part10Dataset::Read(bytes);
  std::vector<std::string> problems;
  const auto type1 = [&](const Part10Item& item, std::uint32_t tag, const char* where) {
    const Part10Element* e = d.Find(item, tag);
    if (e == nullptr || (e->value.empty() && e->item_count == 0)) {
      problems.push_back(fmt::format("{}: Type 1 {} missing or empty", where, TagName(tag)));
    }
  };
  const auto type2 = [&](const Part10Item& item, std::uint32_t tag, const char* where) {
    if (d.Find(item, tag) == nullptr) problems.push_back(fmt::format("{}: Type 2 {} missing", where, TagName(tag)));
  };
  const Part10Item& root = d.root();
  const bool segmented = d.Text(root, 0x00080016).value_or("") == kSegmentedVolumeRenderingPresentationSopClass;
  for (std::uint32_t tag : {0x00100010u, 0x00100020u, 0x00100030u, 0x00100040u}) type2(root, tag, "Patient");
  type1(root, 0x0020000D, "General Study");
  for (std::uint32_t tag : {0x00080020u, 0x00080030u, 0x00080090u, 0x00200010u, 0x00080050u}) {
    type2(root, tag, "General Study");
  }
  type1(root, 0x00080060, "Presentation Series");
  type1(root, 0x0020000E, "General Series");
  type2(root, 0x00200011, "General Series");
  type1(root, 0x00200052, "Frame of Reference");
  type2(root, 0x00201040, "Frame of Reference");
  for (std::uint32_t tag : {0x00080070u, 0x00081090u, 0x00181000u, 0x00181020u}) {
    type1(root, tag, "Enhanced General Equipment");
  }
  for (std::uint32_t tag : {0x00700082u, 0x00700083u, 0x00200013u, 0x00700080u}) {
    type1(root, tag, "Volumetric Presentation State Identification");
  }
  type2(root, 0x00700081, "Volumetric Presentation State Identification");
  for (std::uint32_t tag : {0x0070120Au, 0x00701201u, 0x0070120Bu}) {
    type1(root, tag, "Volumetric Presentation State Relationship");
  }
  for (const Part10Item* set : d.Items(root, 0x0070120A)) {
    for (std::uint32_t tag : {0x00701209u, 0x00701202u, 0x00081140u}) type1(*set, tag, "Input Set item");
    for (const Part10Item* image : d.Items(*set, 0x00081140)) {
      for (std::uint32_t tag : {0x00081150u, 0x00081155u}) type1(*image, tag, "Referenced Image item");
    }
  }
  const std::vector<const Part10Item*> inputs = d.Items(root, 0x00701201);
  if (!segmented && inputs.size() != 1) problems.push_back("B.5.1.24: one input item");
  bool crops = d.Text(root, 0x0070120B).value_or("") == "YES";
  for (const Part10Item* input : inputs) {
    for (std::uint32_t tag : {0x00701207u, 0x00701209u, 0x00701204u, 0x00281050u, 0x00281051u}) {
      type1(*input, tag, "Input item");
    }
    const bool crop = d.Text(*input, 0x00701204).value_or("") == "YES";
    if (!segmented && crop) problems.push_back("B.5.1.24: Crop NO");
    if (crop) type1(*input, 0x00701205, "Cropping Specification Index (1C: Crop YES)");
    crops |= crop;
  }
  if (d.Text(root, 0x0070120B).value_or("") == "YES") type1(root, 0x0070120C, "Global Cropping Specification Index (1C)");
  if (crops) {
    type1(root, 0x00701301, "Volume Cropping (C: a crop)");
    for (const Part10Item* spec : d.Items(root, 0x00701301)) {
      for (std::uint32_t tag : {0x00701309u, 0x00701302u}) type1(*spec, tag, "Volume Cropping item");
      const std::string method = d.Text(*spec, 0x00701302).value_or("");
      if (method == "BOUNDING_BOX") {
        type1(*spec, 0x00701303, "Bounding Box Crop (1C)");
        if (d.Floats(*spec, 0x00701303, 7).size() != 6) problems.push_back("Bounding Box Crop: VM 6");
      } else if (method == "OBLIQUE_PLANES") {
        type1(*spec, 0x00701304, "Oblique Cropping Plane Sequence (1C)");
        for (const Part10Item* plane : d.Items(*spec, 0x00701304)) {
          if (d.Floats(*plane, 0x00701305, 5).size() != 4) problems.push_back("Plane: VM 4");
          if (d.Floats(*plane, 0x00701306, 4).size() != 3) problems.push_back("Plane Normal: VM 3");
        }
      } else if (method == "INCLUDE_SEG" || method == "EXCLUDE_SEG") {
        type1(*spec, 0x00081140, "Referenced Image Sequence (1C: a SEG crop)");
        for (const Part10Item* seg : d.Items(*spec, 0x00081140)) {
          for (std::uint32_t tag : {0x00081150u, 0x00081155u, 0x0062000Bu}) type1(*seg, tag, "the SEG's reference");
        }
      } else {
        problems.push_back("Volume Cropping Method: " + method);
      }
    }
  }
  for (std::uint32_t tag : {0x00082218u, 0x00540220u, 0x00200062u}) type2(root, tag, "Presentation View Description");
  for (std::uint32_t tag : {0x00701602u, 0x00701603u, 0x00701604u, 0x00701605u, 0x00701606u, 0x0070120Du}) {
    type1(root, tag, "Volume Render Geometry");
  }
  for (auto [tag, vm] : {std::pair{0x00701603u, 3u}, {0x00701604u, 3u}, {0x00701605u, 3u}, {0x00701606u, 6u}}) {
    if (d.Floats(root, tag, vm + 1).size() != vm) problems.push_back(fmt::format("{}: VM {}", TagName(tag), vm));
  }
  for (std::uint32_t tag : {0x00701701u, 0x00701702u}) type1(root, tag, "Render Shading");
  for (std::uint32_t tag : {0x00089205u, 0x00701A08u, 0x00282000u}) type1(root, tag, "Render Display");
  type2(root, 0x00701805, "Render Display");
  if (!d.Items(root, 0x00701805).empty()) problems.push_back("one stream: no compositor component");
  const std::vector<const Part10Item*> streams = d.Items(root, 0x00701A08);
  if (streams.size() != 1) problems.push_back("B.5.1.24: one volume stream");
  for (const Part10Item* stream : streams) {
    type1(*stream, 0x00701209, "Volume Stream item");
    type1(*stream, 0x00701801, "Volume Stream item");
    if (d.Items(*stream, 0x00701801).size() != inputs.size()) problems.push_back("a component an input");
    for (const Part10Item* component : d.Items(*stream, 0x00701801)) {
      for (std::uint32_t tag : {0x00701802u, 0x00701803u, 0x0028140Fu, 0x00281410u, 0x00281101u, 0x00281102u,
                                0x00281103u, 0x00281104u, 0x00281201u, 0x00281202u, 0x00281203u, 0x00281204u}) {
        type1(*component, tag, "Classification Component item");
      }
    }
  }
  type1(root, 0x00081115, "Common Instance Reference (1C: this study)");
  for (const Part10Item* series : d.Items(root, 0x00081115)) {
    type1(*series, 0x0020000E, "Referenced Series item");
    type1(*series, 0x0008114A, "Referenced Series item");
  }
  for (std::uint32_t tag : {0x00080016u, 0x00080018u}) type1(root, tag, "SOP Common");
  // The ICC profile is one: its header's signature (ICC.1, 7.2.9).
  const Part10Element* icc = d.Find(root, 0x00282000);
  if (icc == nullptr || icc->value.size() < 128 || icc->value.substr(36, 4) != "acsp") {
    problems.push_back("ICC Profile: not an ICC profile");
  }
  return problems;
}

// Label styles through the SEG the labels came from (the Segmented kind): each visible style its own palette
// (INCLUDE_SEG), the styled ones out of the image's (EXCLUDE_SEG); read back as the same styles, with or without
// cinevol's recipe.
TEST(PresentationState, LabelStylesGoThroughTheSegTheLabelsCameFrom) {
  v1::Scene scene = Scene();
  *scene.mutable_labels() = ParseSceneJson(R"({"labels": {"styles": [
      {"value": 1, "color": {"r": 1, "g": 0.1, "b": 0.1}, "opacityScale": 0.5}, {"value": 5, "visible": false}]}})")
                                .labels();
  const service::SegSource seg{"2.25.3400574.1", "2.25.3400574"};
  PresentationState state = service::PresentationOf(scene, TestVolume(), seg);
  ASSERT_TRUE(state.segmentation);
  const std::string bytes = MakePresentationState(Study(), Source(), state, "0.9.0");
  const std::vector<std::string> problems = ConformanceProblems(bytes);
  EXPECT_TRUE(problems.empty()) << fmt::format("{}", fmt::join(problems, "\n"));
  const ReadPresentation read = ReadPresentationState(bytes);
  ASSERT_TRUE(read.state.segmentation);
  EXPECT_EQ(read.state.segmentation->sop_instance_uid, seg.sop_instance_uid);
  EXPECT_EQ(read.state.segmentation->series_uid, seg.series_uid);
  EXPECT_EQ(read.state.segmentation->styled, (std::vector<std::uint16_t>{1, 5}));
  EXPECT_TRUE(read.state.segmentation->show_unlisted);
  EXPECT_EQ(service::SceneOf(read, kAxialAxes).labels().DebugString(), scene.labels().DebugString());

  state.recipe_json.clear();  // another system's copy
  const v1::Labels labels =
      service::SceneOf(ReadPresentationState(MakePresentationState(Study(), Source(), state, "0.9.0")), kAxialAxes)
          .labels();
  ASSERT_EQ(labels.styles_size(), 2);
  EXPECT_NEAR(labels.styles(0).color().r(), 1, 1e-4);
  EXPECT_NEAR(labels.styles(0).color().g(), 0.1, 1e-4);
  EXPECT_NEAR(labels.styles(0).opacity_scale(), 0.5, 1e-3);
  EXPECT_FALSE(labels.styles(1).visible());
}

TEST(PresentationState, FollowsTheIodsModuleTables) {
  const std::vector<std::string> problems =
      ConformanceProblems(MakePresentationState(Study(), Source(), State(), "0.9.0"));
  EXPECT_TRUE(problems.empty()) << fmt::format("{}", fmt::join(problems, "\n"));
}

// Debian's dciodvfy has this SOP class's attributes but not its IOD: it checks every value against its VR and
// dictionary, then says it has no IOD to check against. No other error, and only the warnings docs/pacs.md lists.
TEST(PresentationState, DciodvfyFindsNoErrorButItsMissingIod) {
  ASSERT_TRUE(Installed("dciodvfy")) << "dciodvfy (dicom3tools) is not installed: run scripts/install-deps.sh";
  ScratchDir scratch;
  const fs::path file = scratch / "presentation.dcm";
  WriteFile(file, MakePresentationState(Study(), Source(), State(), "0.9.0"));
  const CommandResult result = RunCommand("dciodvfy '" + file.string() + "'");
  std::istringstream lines(result.output);
  for (std::string line; std::getline(lines, line);) {
    if (line.find("Error") != std::string::npos) {
      EXPECT_EQ(line, "Error - Information Object Not found") << result.output;
    }
    if (line.find("Warning") != std::string::npos) {
      const bool listed = line.find("Unrecognized tag") != std::string::npos && line.find("0x0041") != std::string::npos;
      EXPECT_TRUE(listed) << "a warning not in docs/pacs.md: " << line << "\n" << result.output;
    }
  }
  ASSERT_TRUE(Installed("dcmdump")) << "dcmdump (DCMTK) is not installed: run scripts/install-deps.sh";
  const CommandResult dump = RunCommand("dcmdump '" + file.string() + "'");
  EXPECT_EQ(dump.status, 0) << dump.output;
  EXPECT_NE(dump.output.find("VolumeRenderingVolumetricPresentationStateStorage"), std::string::npos) << dump.output;
  EXPECT_NE(dump.output.find("ViewpointLookAtPoint"), std::string::npos) << dump.output;
}

TEST(PresentationState, HostileInputsAreRefusedNamingTheField) {
  const auto refused = [](auto change) {
    PresentationState state = State();
    SourceStudy study = Study();
    ReportSource source = Source();
    change(state, study, source);
    return ErrorOf<InputError>([&] { MakePresentationState(study, source, state, "0.9.0"); });
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(refused([&](auto& s, auto&, auto&) { s.geometry.viewpoint[1] = nan; }).find("geometry.viewpoint"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.geometry.look_at = s.geometry.viewpoint; }).find("geometry"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.geometry.field_of_view[4] = 0; }).find("field_of_view"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.classification.rgba.resize(5); }).find("classification.rgba"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.classification.window_width = 0; }).find("window"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.label = "lower case"; }).find("label"), std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.description = std::string(65, 'x'); }).find("description"),
            std::string::npos);
  EXPECT_NE(refused([](auto&, auto& study, auto&) { study.patient_id = std::string(65, '1'); }).find("patient_id"),
            std::string::npos);
  EXPECT_NE(refused([](auto&, auto& study, auto&) { study.study_uid = "1.2.x"; }).find("study_uid"),
            std::string::npos);
  EXPECT_NE(refused([](auto&, auto&, auto& source) { source.images.clear(); }).find("source.images"),
            std::string::npos);
  EXPECT_NE(refused([](auto& s, auto&, auto&) { s.cropping.plane_sets.push_back({}); }).find("plane_sets"),
            std::string::npos);
}

// What cinevol does not read is refused saying so: another class, several inputs, an orthographic view.
TEST(PresentationState, ReadRefusesWhatItCannotShowByName) {
  const std::string bytes = MakePresentationState(Study(), Source(), State(), "0.9.0");
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string copy = bytes;  // every occurrence, by one of the same length: the file stays well formed
    for (std::size_t at = copy.find(from); at != std::string::npos; at = copy.find(from, at)) copy.replace(at, from.size(), to);
    return copy;
  };
  EXPECT_NE(ErrorOf<InputError>([&] {
              ReadPresentationState(replaced("1.2.840.10008.5.1.4.1.1.11.9", "1.2.840.10008.5.1.4.1.1.11.8"));
            }).find("its SOP class is 1.2.840.10008.5.1.4.1.1.11.8"),
            std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([&] {
              service::SceneOf(ReadPresentationState(replaced("PERSPECTIVE", "ORTHOGRAPHI")), kAxialAxes);
            }).find("Render Projection"),
            std::string::npos);
  PresentationState orthographic = State();
  orthographic.geometry.perspective = false;
  EXPECT_NE(ErrorOf<InputError>([&] {
              service::SceneOf(
                  ReadPresentationState(MakePresentationState(Study(), Source(), orthographic, "0.9.0")), kAxialAxes);
            }).find("ORTHOGRAPHIC"),
            std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([&] { ReadPresentationState("not DICOM"); }).find("DICOM"), std::string::npos);
}

// Every truncation, and a corrupted byte at every 7th position: read or refused with InputError, never a crash.
TEST(PresentationState, ReadSurvivesEveryTruncationAndCorruptedByte) {
  PresentationState state = State();
  state.classification.rgba.resize(kPaletteEntries);
  const std::string bytes = MakePresentationState(Study(), Source(), state, "0.9.0");
  std::size_t refused = 0, read = 0;
  const auto attempt = [&](std::string b) {
    try {
      const ReadPresentation r = ReadPresentationState(std::move(b));
      service::SceneOf(r, kAxialAxes);
      ++read;
    } catch (const InputError&) {
      ++refused;
    }
  };
  for (std::size_t n = 0; n < bytes.size(); n += 97) attempt(bytes.substr(0, n));
  for (std::size_t i = 132; i < bytes.size(); i += 7) {
    std::string corrupted = bytes;
    corrupted[i] = char(corrupted[i] ^ 0x5A);
    attempt(std::move(corrupted));
  }
  EXPECT_GT(refused, 0u);
  EXPECT_GT(read, 0u);
}

}  // namespace
}  // namespace cinevol::pacs

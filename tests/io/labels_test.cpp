// Segmentations: label tables, fitting a label volume to its image's grid,
// and the real 117-label TotalSegmentator CT rendered with labels shown and
// hidden (issue 22).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <set>

#include "core/error.h"
#include "io/label_volume.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "io/table_finder.h"
#include "pipeline/frame_pipeline.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::SharedData;

std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(LabelTable, ReadsValueTabNameLinesAndSkipsComments) {
  const auto names = ParseLabelTable("# label\\tname\n1\tspleen\r\n\n5\tliver\n65535\tlast one\n", "t.tsv");
  ASSERT_EQ(names.size(), 3u);
  EXPECT_EQ(names.at(1), "spleen");
  EXPECT_EQ(names.at(5), "liver");
  EXPECT_EQ(names.at(65535), "last one");
}

TEST(LabelTable, ABadLineGetsAnErrorNamingTheLine) {
  EXPECT_NE(MessageOf([] {
              ParseLabelTable("1\tspleen\nliver 5\n", "t.tsv");
            }).find("t.tsv line 2: expected 'value<TAB>name'"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { ParseLabelTable("1\tspleen\n\n70000\tx\n", "t.tsv"); }).find("line 3"), std::string::npos);
  EXPECT_NE(MessageOf([] { ParseLabelTable("-1\tx\n", "t.tsv"); }).find("line 1"), std::string::npos);
  EXPECT_NE(MessageOf([] { ParseLabelTable("4\t\n", "t.tsv"); }).find("line 1: the name"), std::string::npos);
  EXPECT_NE(MessageOf([] { ParseLabelTable("4\ta\n4\tb\n", "t.tsv"); }).find("line 2: label 4 is named twice"),
            std::string::npos);
}

Volume Grid(Vec3i dims, Vec3f spacing, std::array<double, 3> origin, std::vector<float> values) {
  VolumeMetadata meta;
  meta.source = "grid";
  meta.origin_mm = origin;
  return Volume(dims, spacing, std::move(values), meta);
}

TEST(LabelVolume, OnTheSameGridIsTakenAsItIs) {
  const Volume image = Grid({2, 2, 2}, {1, 1, 1}, {10, 20, 30}, std::vector<float>(8, 0.0f));
  const Volume labels = Grid({2, 2, 2}, {1, 1, 1}, {10, 20, 30}, {0, 1, 2, 3, 4, 5, 6, 7});
  const LabelVolume fitted = FitLabels(labels, image, "labels.nii");
  EXPECT_TRUE(fitted.note.empty()) << fitted.note;
  for (int i = 0; i < 8; ++i) EXPECT_EQ(fitted.LabelOf(fitted.labels[i]), i) << "voxel " << i;
  EXPECT_EQ(fitted.labels[0], 8) << "voxel 0 touches labels 1..7: their shell";
  EXPECT_EQ(fitted.voxels.at(7), 1u);
}

TEST(LabelVolume, OnAnotherGridIsResampledNearestNeighbour) {
  // The image: 8^3 voxels of 1 mm at the origin. The labels: 4^3 of 2 mm
  // whose first centre sits half a millimetre on, so image voxel x takes
  // label voxel x / 2; a label is its label voxel's x index + 1.
  const Volume image = Grid({8, 8, 8}, {1, 1, 1}, {0, 0, 0}, std::vector<float>(512, 0.0f));
  std::vector<float> own(64);
  for (std::size_t i = 0; i < own.size(); ++i) own[i] = float(i % 4 + 1);
  const LabelVolume fitted = FitLabels(Grid({4, 4, 4}, {2, 2, 2}, {0.5, 0.5, 0.5}, own), image, "labels.nii");
  EXPECT_NE(fitted.note.find("resampled nearest-neighbour"), std::string::npos) << fitted.note;
  for (int x = 0; x < 8; ++x) EXPECT_EQ(fitted.labels[x], x / 2 + 1) << "image voxel x " << x;
  // Shifted half its size away, half the image lies outside: label 0 there, and said so.
  const LabelVolume half = FitLabels(Grid({4, 4, 4}, {2, 2, 2}, {4.5, 0.5, 0.5}, own), image, "labels.nii");
  EXPECT_EQ(half.labels[0], 0);
  EXPECT_EQ(half.labels[7], 2);
  EXPECT_NE(half.note.find("voxels outside it are label 0"), std::string::npos) << half.note;
}

TEST(LabelVolume, ThatMissesTheImageOrHoldsNonIntegersIsRefused) {
  const Volume image = Grid({4, 4, 4}, {1, 1, 1}, {0, 0, 0}, std::vector<float>(64, 0.0f));
  EXPECT_NE(MessageOf([&] {
              FitLabels(Grid({4, 4, 4}, {1, 1, 1}, {500, 0, 0}, std::vector<float>(64, 1.0f)), image, "seg.nii");
            }).find("seg.nii: its grid (4x4x4 voxels of 1x1x1 mm at (500, 0, 0)) does not overlap the image's"),
            std::string::npos);
  std::vector<float> half(64, 1.0f);
  half[9] = 2.5f;
  EXPECT_NE(MessageOf([&] { FitLabels(Grid({4, 4, 4}, {1, 1, 1}, {0, 0, 0}, half), image, "seg.nii"); })
                .find("seg.nii: voxel 9 holds 2.5"),
            std::string::npos);
}

// Segmentations at the extremes: grids a million times finer or coarser than
// their image's, one voxel, far away, singular, or labels no uint16 holds.
TEST(LabelVolume, AtTheExtremesFitsOrIsRefusedClearly) {
  const Volume image = Grid({8, 8, 8}, {1e3f, 1e3f, 1e3f}, {0, 0, 0}, std::vector<float>(512, 0.0f));
  // One label voxel of 1e4 mm over the image's first five voxels along each axis.
  const LabelVolume coarse = FitLabels(Grid({1, 1, 1}, {1e4f, 1e4f, 1e4f}, {0, 0, 0}, {3.0f}), image, "seg.nii");
  EXPECT_EQ(coarse.labels[0], 3);
  EXPECT_EQ(coarse.labels[7], 0);  // x = 7000 mm: outside the label voxel
  EXPECT_EQ(coarse.voxels.at(3), 5u * 5 * 5);
  // Labels of 1e-3 mm: image voxel i lands on label index 1e6 i, past any int; only the first is inside.
  const LabelVolume fine = FitLabels(Grid({2, 2, 2}, {1e-3f, 1e-3f, 1e-3f}, {0, 0, 0}, std::vector<float>(8, 1.0f)),
                                     image, "seg.nii");
  EXPECT_EQ(fine.voxels.at(1), 1u);
  // Far away, at the largest spacing: the grids do not meet.
  EXPECT_NE(MessageOf([&] {
              FitLabels(Grid({4, 4, 4}, {1e4f, 1e4f, 1e4f}, {1e300, -1e300, 0}, std::vector<float>(64, 1.0f)), image,
                        "seg.nii");
            }).find("does not overlap"),
            std::string::npos);
  // Direction cosines that collapse an axis.
  {
    VolumeMetadata meta;
    meta.source = "seg.nii";
    meta.direction = {1, 0, 0, 1, 0, 0, 0, 0, 1};
    const Volume flat({2, 2, 2}, {1, 1, 1}, std::vector<float>(8, 1.0f), meta);
    EXPECT_NE(MessageOf([&] { FitLabels(flat, image, "seg.nii"); }).find("singular"), std::string::npos);
  }
  // Values no label holds, named as they are.
  EXPECT_NE(MessageOf([&] { FitLabels(Grid({1, 1, 1}, {1, 1, 1}, {0, 0, 0}, {1e30f}), image, "seg.nii"); })
                .find("seg.nii: voxel 0 holds 1e+30, not an integer label in [0, 65535]"),
            std::string::npos);
  EXPECT_NE(MessageOf([&] { FitLabels(Grid({1, 1, 1}, {1, 1, 1}, {0, 0, 0}, {-1.0f}), image, "seg.nii"); })
                .find("holds -1,"),
            std::string::npos);
}

// The real TotalSegmentator segmentation on its CT, through the renderer.
class TotalSegmentator : public ::testing::Test {
 protected:
  void SetUp() override {
    CINEVOL_REQUIRE_SHARED_DATA();
    const auto folder = SharedData() / "ct-body-totalsegmentator";
    image_ = std::make_shared<const Volume>(LoadVolumeFile(folder / "example_ct_sm.nii.gz"));
    auto labels = LoadLabelVolume(folder / "example_seg.nii.gz", *image_);
    labels.names = LoadLabelTable(folder / "labels-total.tsv", "labels-total.tsv");
    labels_ = std::make_shared<const LabelVolume>(std::move(labels));
  }

  // The voxels where camera rays first met tissue, at 96x96, under `styles`
  // and `preset`, with `labels` (default: the segmentation as loaded).
  std::vector<std::size_t> FirstHitVoxels(const v1::Labels& styles, std::shared_ptr<const LabelVolume> labels = nullptr,
                                          const std::string& preset = "ct-soft-tissue") const {
    return FirstHitVoxelsFrom(v1::ANTERIOR, styles, std::move(labels), preset);
  }
  std::vector<std::size_t> FirstHitVoxelsFrom(v1::NamedView view, const v1::Labels& styles,
                                              std::shared_ptr<const LabelVolume> labels,
                                              const std::string& preset = "ct-soft-tissue") const {
    v1::Scene scene = MakePresetScene(preset, *image_);
    scene.mutable_camera()->set_view(view);
    scene.mutable_render()->set_width(96);
    scene.mutable_render()->set_height(96);
    scene.mutable_render()->set_spp(2);
    *scene.mutable_labels() = styles;
    ApplyDefaults(scene);
    FramePipeline pipeline(Backend::kCpu, image_, {}, labels ? labels : labels_);
    FrameSettings settings;
    settings.denoiser.method = DenoiseMethod::kNone;
    pipeline.Update(scene, settings);
    pipeline.RenderFrame();
    const Vec3f extent = image_->extent_mm(), spacing = image_->spacing_mm();
    std::vector<std::size_t> voxels;
    for (const Vec4f& h : pipeline.FirstHits()) {
      if (h.w == 0) continue;
      Vec3i v;
      for (int a = 0; a < 3; ++a) {
        const float q = (Xyz(h)[a] + 0.5f * extent[a]) / spacing[a] - 0.5f;
        v[a] = std::clamp(int(std::floor(q + 0.5f)), 0, image_->dims()[a] - 1);
      }
      voxels.push_back((std::size_t(v.z) * image_->dims().y + v.y) * image_->dims().x + v.x);
    }
    return voxels;
  }

  // The labels of the voxels where camera rays first met tissue (stored
  // values: shells have values of their own).
  std::map<int, int> FirstHitLabels(const v1::Labels& styles) const {
    std::map<int, int> hits;
    for (std::size_t v : FirstHitVoxels(styles)) ++hits[labels_->labels[v]];
    return hits;
  }

  // The ribs, sternum and costal cartilages hidden: examples/ct-body-no-ribs.json.
  v1::Labels NoRibs() const {
    v1::Labels no_ribs;
    for (const auto& [value, name] : labels_->names) {
      if (name.rfind("rib_", 0) != 0 && name != "sternum" && name != "costal_cartilages") continue;
      v1::LabelStyle* style = no_ribs.add_styles();
      style->set_value(value);
      style->set_visible(false);
    }
    return no_ribs;
  }

  std::shared_ptr<const Volume> image_;
  std::shared_ptr<const LabelVolume> labels_;
};

TEST_F(TotalSegmentator, ItsTableNamesItsLabels) {
  EXPECT_EQ(labels_->names.size(), 117u);
  EXPECT_EQ(labels_->names.at(5), "liver");
  EXPECT_TRUE(labels_->note.empty()) << "example_seg shares example_ct_sm's grid: " << labels_->note;
  EXPECT_GT(labels_->voxels.at(5), 1000u) << "liver voxels";
}

TEST_F(TotalSegmentator, TheLiverAloneVisibleShowsOnlyLiver) {
  v1::Labels liver_alone;
  liver_alone.set_show_unlisted(false);
  liver_alone.add_styles()->set_value(5);
  const std::map<int, int> hits = FirstHitLabels(liver_alone);
  std::string seen;
  for (const auto& [label, count] : hits) seen += fmt::format(" {}:{}", label, count);
  ASSERT_EQ(hits.size(), 1u) << "labels hit (label:pixels):" << seen;
  EXPECT_EQ(hits.begin()->first, 5);
  EXPECT_GT(hits.begin()->second, 200) << "pixels showing the liver";
}

// example_seg covers the first 30 of example_ct's 112 slices (the same
// origin, spacing and direction): fitted to example_ct it is resampled, the
// slices beyond it label 0, its own voxels where it lies.
TEST_F(TotalSegmentator, OnTheLongerCtTheSegmentationIsResampledAndSaysSo) {
  const auto folder = SharedData() / "ct-body-totalsegmentator";
  const Volume long_ct = LoadVolumeFile(folder / "example_ct.nii.gz");
  const LabelVolume fitted = LoadLabelVolume(folder / "example_seg.nii.gz", long_ct);
  EXPECT_NE(fitted.note.find("resampled nearest-neighbour"), std::string::npos) << fitted.note;
  EXPECT_NE(fitted.note.find("voxels outside it are label 0"), std::string::npos) << fitted.note;
  const std::size_t slice = std::size_t(long_ct.dims().x) * long_ct.dims().y;
  ASSERT_EQ(fitted.labels.size(), slice * long_ct.dims().z);
  EXPECT_TRUE(std::equal(labels_->labels.begin(), labels_->labels.end(), fitted.labels.begin()))
      << "where they overlap, the labels are example_seg's own";
  EXPECT_TRUE(std::all_of(fitted.labels.begin() + std::ptrdiff_t(slice * 30), fitted.labels.end(),
                          [&](std::uint16_t l) { return fitted.LabelOf(l) == 0; }))
      << "beyond it label 0 (the shell of slice 29's labels in slice 30 among it)";
}

// example_seg_dicom is stored with its y axis flipped against the DICOM
// series (LAS against LPS, origin at the other end): the same voxels, indexed
// the other way. Fitted, every voxel finds its own label: the counts agree.
TEST(LabelVolumeOnDicom, AFlippedAxisIsResampledVoxelForVoxel) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const auto folder = SharedData() / "ct-body-totalsegmentator";
  const Volume ct = LoadDicomSeries(folder / "example_ct_dicom");
  const Volume own = LoadVolumeFile(folder / "example_seg_dicom.nii.gz");
  const LabelVolume fitted = FitLabels(own, ct, "example_seg_dicom.nii.gz");
  EXPECT_NE(fitted.note.find("resampled"), std::string::npos) << fitted.note;
  EXPECT_EQ(fitted.note.find("outside"), std::string::npos) << "the grids cover each other: " << fitted.note;
  std::map<int, std::uint64_t> counts;
  for (std::size_t i = 0; i < own.voxel_count(); ++i) ++counts[int(own.ValueAtIndex(i))];
  EXPECT_EQ(fitted.voxels, counts);
  EXPECT_GT(fitted.voxels.at(5), 100000u) << "liver voxels";
}

// A named view frames what the labels leave visible: the liver alone is
// seen from closer than the whole body, centred on it.
TEST_F(TotalSegmentator, NamedViewsFrameTheVisibleLabels) {
  v1::Camera anterior;
  anterior.set_view(v1::ANTERIOR);
  anterior.set_fov_y_deg(30);
  v1::RenderSettings render;
  render.set_width(96);
  render.set_height(96);
  const TransferFunction tf =
      ResolveTransferFunction(MakePresetScene("ct-soft-tissue", *image_).transfer_function(), *image_);
  LabelSetup liver_alone;
  liver_alone.show_unlisted = false;
  liver_alone.styles[5] = {};
  const std::vector<bool> all_blocks = BlocksWithVisibleLabels(*image_, *labels_, {});
  const std::vector<bool> liver_blocks = BlocksWithVisibleLabels(*image_, *labels_, liver_alone);
  InView all_labels, liver_only;
  all_labels.label_blocks = &all_blocks;
  liver_only.label_blocks = &liver_blocks;
  const Camera whole = ResolveCamera(anterior, render, *image_, tf, all_labels);
  const Camera liver = ResolveCamera(anterior, render, *image_, tf, liver_only);
  EXPECT_LT(liver.focal_distance, 0.8f * whole.focal_distance) << "the view comes closer to the liver";
}

TEST_F(TotalSegmentator, TheRibsHiddenShowNoRib) {
  v1::Labels no_ribs;
  int ribs_present = 0;
  for (const auto& [value, name] : labels_->names) {
    if (name.rfind("rib_", 0) != 0) continue;
    v1::LabelStyle* style = no_ribs.add_styles();
    style->set_value(value);
    style->set_visible(false);
    ribs_present += labels_->voxels.count(value);
  }
  ASSERT_GT(ribs_present, 0) << "the segmentation holds ribs";
  const std::map<int, int> all = FirstHitLabels({}), hidden = FirstHitLabels(no_ribs);
  int rib_hits_before = 0;
  for (const v1::LabelStyle& style : no_ribs.styles()) {
    EXPECT_EQ(hidden.count(int(style.value())), 0u) << "rib label " << style.value() << " still shows";
    rib_hits_before += all.count(int(style.value())) ? all.at(int(style.value())) : 0;
  }
  EXPECT_GT(rib_hits_before, 0) << "ribs show while visible";
}

// A voxel's 26 neighbours hold a label `hidden` says is hidden, while it holds none.
bool TouchesHidden(const LabelVolume& l, std::size_t i, const std::set<int>& hidden) {
  const Vec3i d = l.dims;
  const int x = int(i % d.x), y = int(i / d.x % d.y), z = int(i / (std::size_t(d.x) * d.y));
  if (l.LabelOf(l.labels[i]) != 0) return false;
  for (int nz = std::max(0, z - 1); nz <= std::min(d.z - 1, z + 1); ++nz)
    for (int ny = std::max(0, y - 1); ny <= std::min(d.y - 1, y + 1); ++ny)
      for (int nx = std::max(0, x - 1); nx <= std::min(d.x - 1, x + 1); ++nx)
        if (hidden.count(l.LabelOf(l.labels[(std::size_t(nz) * d.y + ny) * d.x + nx]))) return true;
  return false;
}

// The same labels without shells: what FitLabels made before issue 32.
std::shared_ptr<const LabelVolume> WithoutShells(const LabelVolume& labels) {
  auto bare = std::make_shared<LabelVolume>(labels);
  for (std::uint16_t& v : bare->labels) v = std::uint16_t(labels.LabelOf(v));
  bare->derived.clear();
  return bare;
}

// Issue 32: "with the ribs hidden, their partial-volume shell still shows as
// speckled arcs". Under ct-bone (examples/ct-body-no-ribs.json) first hits on
// unlabelled voxels touching a hidden rib, sternum or cartilage were the arcs.
TEST_F(TotalSegmentator, TheRibsHiddenTakeTheirShellAlong) {
  const v1::Labels no_ribs = NoRibs();
  std::set<int> hidden;
  for (const v1::LabelStyle& style : no_ribs.styles()) hidden.insert(int(style.value()));
  auto on_shell = [&](const std::vector<std::size_t>& hits) {
    return std::count_if(hits.begin(), hits.end(), [&](std::size_t v) { return TouchesHidden(*labels_, v, hidden); });
  };
  const auto before = FirstHitVoxels(no_ribs, WithoutShells(*labels_), "ct-bone");
  const auto after = FirstHitVoxels(no_ribs, labels_, "ct-bone");
  const auto shown = FirstHitVoxels({}, labels_, "ct-bone");
  std::printf("first hits under ct-bone at 96x96: ribs shown %zu; ribs hidden %zu, on their shell %ld without shells, "
              "%zu and %ld with\n",
              shown.size(), before.size(), long(on_shell(before)), after.size(), long(on_shell(after)));
  EXPECT_GT(on_shell(before), 20) << "the arcs: first hits on the ribs' unlabelled rim";
  EXPECT_EQ(on_shell(after), 0) << "no first hit touches a hidden label";
  // What else shows stays: the spine, pelvis and the rest of the skeleton.
  const auto off_ribs = [&](const std::vector<std::size_t>& hits) {
    return std::count_if(hits.begin(), hits.end(), [&](std::size_t v) {
      return !hidden.count(labels_->LabelOf(labels_->labels[v])) && !TouchesHidden(*labels_, v, hidden);
    });
  };
  EXPECT_GT(off_ribs(after), 0.9 * off_ribs(before)) << "the rest of the skeleton still shows";
}

// Issue 32: the table removed beside a real segmentation. The table search
// knows nothing of the labels, yet none of TotalSegmentator's 117 structures
// has a voxel in what it hides; removed with the ribs hidden, neither shows,
// and the rest does.
TEST_F(TotalSegmentator, TheTableGoesTheLabelsStay) {
  const TableMask table = FindTable(*image_);
  ASSERT_TRUE(table.found()) << table.note;
  std::uint64_t labelled_in_table = 0;
  for (std::size_t i = 0; i < labels_->labels.size(); ++i) {
    labelled_in_table +=
        labels_->LabelOf(labels_->labels[i]) != 0 && (table.voxels[i] & (kTableVoxel | kTableRimVoxel));
  }
  EXPECT_EQ(labelled_in_table, 0u) << "labelled voxels the table search would hide";
  auto both = std::make_shared<LabelVolume>(*labels_);
  AddTable(*both, table);
  EXPECT_EQ(both->table_voxels, table.table_voxels + table.rim_voxels);

  v1::Labels styles = NoRibs();
  styles.set_remove_table(true);
  std::set<int> ribs;
  for (const v1::LabelStyle& style : styles.styles()) ribs.insert(int(style.value()));
  int on_table = 0, on_ribs = 0, on_liver = 0;
  for (v1::NamedView view : {v1::ANTERIOR, v1::POSTERIOR}) {
    for (std::size_t v : FirstHitVoxelsFrom(view, styles, both)) {
      on_table += both->labels[v] == both->table_value();
      on_ribs += ribs.count(both->LabelOf(both->labels[v])) > 0;
      on_liver += both->LabelOf(both->labels[v]) == 5;
    }
  }
  EXPECT_EQ(on_table, 0);
  EXPECT_EQ(on_ribs, 0);
  EXPECT_GT(on_liver, 100) << "the liver shows through the ribs' gaps";
}

TEST(LabelShells, EachSetOfLabelsTouchedGetsAValueThatHidesWithThem) {
  // 8x4x4: label 1 at x = 1, label 2 at x = 5; x = 3 touches neither, x = 4
  // touches only 2, x = 0 and 2 only 1; x = 6, 7 only 2.
  LabelVolume l;
  l.dims = {8, 4, 4};
  l.labels.assign(128, 0);
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) l.labels[(z * 4 + y) * 8 + 1] = 1, l.labels[(z * 4 + y) * 8 + 5] = 2;
  for (std::uint16_t v : l.labels) ++l.voxels[v];
  AddShells(l);
  ASSERT_EQ(l.first_derived, 3);
  ASSERT_EQ(l.derived.size(), 2u);
  EXPECT_EQ(l.value_count(), 5);
  auto value_at = [&](int x) { return int(l.labels[x]); };
  EXPECT_EQ(value_at(3), 0) << "touches no label";
  EXPECT_EQ(value_at(0), value_at(2));
  EXPECT_EQ(l.derived[value_at(0) - 3].touches, (std::vector<std::uint16_t>{1}));
  EXPECT_EQ(l.derived[value_at(4) - 3].touches, (std::vector<std::uint16_t>{2}));
  EXPECT_EQ(l.LabelOf(value_at(0)), 0) << "to everything but the renderer, a shell is label 0";
  EXPECT_EQ(l.voxels.at(0), 128u - 32u) << "voxel counts stay the segmentation's";

  LabelSetup hide_one;
  hide_one.styles[1].visible = false;
  EXPECT_TRUE(hide_one.StyleOfValue(l, value_at(0)).hidden());
  EXPECT_FALSE(hide_one.StyleOfValue(l, value_at(4)).hidden()) << "label 2's shell stays";
  LabelSetup one_alone;
  one_alone.show_unlisted = false;
  one_alone.styles[1] = {};
  EXPECT_TRUE(one_alone.StyleOfValue(l, value_at(0)).hidden()) << "a shell is label 0: hidden with the unlisted";
  LabelSetup faint;
  faint.styles[1].opacity_scale = 0.2f;
  EXPECT_EQ(faint.StyleOfValue(l, value_at(0)).opacity_scale, 1.0f) << "only hiding carries over to the shell";
  EXPECT_FALSE(LabelSetup{}.ChangesAnything(l)) << "default styles: renderers skip the lookup";
  EXPECT_TRUE(hide_one.ChangesAnything(l));
}

}  // namespace
}  // namespace cinevol

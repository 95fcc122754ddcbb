// Table removal (issue 32): FindTable on a synthetic patient on a curved
// table, and on the shared chest and abdomen CTs through the renderer: no
// first hit on the table once it is removed, the body as it was.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "io/label_volume.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "io/table_finder.h"
#include "scene/volume_kind.h"
#include "io/volume_loader.h"
#include "pipeline/frame_pipeline.h"
#include "support/patient_on_table.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::PatientOnTable;
using testing::SharedData;

Volume Synthetic(const PatientOnTable& p, const std::string& modality = "CT") {
  std::vector<float> values(std::size_t(p.dims.x) * p.dims.y * p.dims.z);
  std::size_t i = 0;
  for (int z = 0; z < p.dims.z; ++z)
    for (int y = 0; y < p.dims.y; ++y)
      for (int x = 0; x < p.dims.x; ++x) values[i++] = p.Hu(x, y, z);
  VolumeMetadata meta;
  meta.source = "patient on a table";
  meta.modality = modality;
  return Volume(p.dims, {p.spacing_mm, p.spacing_mm, p.spacing_mm}, std::move(values), meta);
}

// What FindTable made of each part of the synthetic patient: voxels, and how
// many of them it marked table (or rim).
struct Tally {
  std::uint64_t table = 0, table_marked = 0;      // the table's own voxels
  std::uint64_t patient = 0, patient_marked = 0;  // trunk, lungs, spine and arm
  std::uint64_t lead = 0, lead_marked = 0;
};

Tally Count(const PatientOnTable& p, const TableMask& m) {
  Tally t;
  std::size_t i = 0;
  for (int z = 0; z < p.dims.z; ++z)
    for (int y = 0; y < p.dims.y; ++y)
      for (int x = 0; x < p.dims.x; ++x, ++i) {
        const float mx = (float(x) + 0.5f) * p.spacing_mm, my = (float(y) + 0.5f) * p.spacing_mm;
        const bool marked = !m.voxels.empty() && (m.voxels[i] & (kTableVoxel | kTableRimVoxel));
        if (p.InTrunk(mx, my, z) || p.InArm(mx, my)) {
          ++t.patient;
          t.patient_marked += marked;
        } else if (p.InTable(mx, my)) {
          ++t.table;
          t.table_marked += marked;
        } else if (p.InLead(mx, my, z)) {
          ++t.lead;
          t.lead_marked += marked;
        }
      }
  return t;
}

TEST(TableFinder, FindsACurvedTableUnderThePatientAndNothingOfThePatient) {
  const PatientOnTable patient;
  const TableMask m = FindTable(Synthetic(patient));
  ASSERT_TRUE(m.found()) << m.note;
  const Tally t = Count(patient, m);
  EXPECT_EQ(t.table_marked, t.table) << "every voxel of the table";
  EXPECT_EQ(t.patient_marked, 0u) << "none of the trunk, lungs, spine or arm (a thick component of its own)";
  EXPECT_GT(t.lead, 0u);
  EXPECT_EQ(t.lead_marked, 0u) << "a lead along a quarter of the scan is not a table";
  EXPECT_GT(m.rim_voxels, 0u) << "the table's rim goes with it";
  EXPECT_EQ(m.table_components, 1);
  EXPECT_NE(m.note.find("table: 1 component"), std::string::npos) << m.note;
}

// The back rests on the table in 40% of the slices. There the opening gives
// the table near the skin to the body; but the table lies where it lies in
// the other slices too, and its profile from them takes it back.
TEST(TableFinder, ATableTheBackRestsOnInPartOfTheScanComesOffThere) {
  PatientOnTable patient;
  patient.resting_slices = 16;
  const TableMask m = FindTable(Synthetic(patient));
  ASSERT_TRUE(m.found()) << m.note;
  const Tally t = Count(patient, m);
  EXPECT_EQ(t.patient_marked, 0u);
  EXPECT_EQ(t.table_marked, t.table) << t.table_marked << " of " << t.table;

  // Resting on it throughout, the table within a voxel or two of the skin
  // stays with the body where the two curves run close.
  patient.resting_slices = patient.dims.z;
  const TableMask resting = FindTable(Synthetic(patient));
  const Tally r = Count(patient, resting);
  EXPECT_EQ(r.patient_marked, 0u);
  EXPECT_GT(double(r.table_marked), 0.4 * double(r.table)) << r.table_marked << " of " << r.table;
}

TEST(TableFinder, SearchesNeitherMrNorCropsWithoutTable) {
  const PatientOnTable patient;
  const TableMask mr = FindTable(Synthetic(patient, "MR"));
  EXPECT_FALSE(mr.found());
  EXPECT_NE(mr.note.find("MR: no table search"), std::string::npos) << mr.note;
  EXPECT_TRUE(mr.voxels.empty());

  // The trunk alone, cropped so it reaches every face: lungs open to the
  // crop's edge are thick, nothing thin runs along outside it.
  std::vector<float> crop;
  const Vec3i dims{40, 30, 40};
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) crop.push_back(patient.Hu(x + 20, y + 20, z));
  VolumeMetadata meta;
  meta.modality = "CT";
  const TableMask cropped = FindTable(Volume(dims, {2.5f, 2.5f, 2.5f}, std::move(crop), meta));
  EXPECT_FALSE(cropped.found()) << cropped.note;
}

TEST(TableFinder, StopsWhenCancelled) {
  std::atomic<bool> cancel{true};
  TableSettings settings;
  settings.cancel = &cancel;
  EXPECT_THROW(FindTable(Synthetic(PatientOnTable{}), settings), Cancelled);
}

TEST(TableFinder, MarksTheTableBesideASegmentationWithoutTouchingItsLabels) {
  const PatientOnTable patient;
  const Volume image = Synthetic(patient);
  const TableMask m = FindTable(image);
  // A segmentation labelling the spine 1 (and, wrongly, one table voxel 2).
  LabelVolume labels;
  labels.dims = image.dims();
  labels.labels.assign(image.voxel_count(), 0);
  std::size_t table_voxel = 0;
  for (std::size_t i = 0; i < labels.labels.size(); ++i) {
    if (image.ValueAtIndex(i) == 700.0f) labels.labels[i] = 1;
    if ((m.voxels[i] & kTableVoxel) && table_voxel == 0) table_voxel = i;
  }
  labels.labels[table_voxel] = 2;
  for (std::uint16_t l : labels.labels) ++labels.voxels[l];
  const std::uint64_t spine = labels.voxels.at(1);
  AddShells(labels);
  AddTable(labels, m);
  const int table = labels.table_value();
  ASSERT_GT(table, 2);
  EXPECT_EQ(labels.labels[table_voxel], 2) << "a labelled voxel keeps its label";
  EXPECT_EQ(labels.table_voxels, m.table_voxels + m.rim_voxels - 1);
  EXPECT_EQ(labels.LabelOf(table), 0);
  EXPECT_EQ(labels.voxels.at(1), spine) << "the segmentation's counts stay";
  EXPECT_EQ(std::count(labels.labels.begin(), labels.labels.end(), std::uint16_t(1)), std::ptrdiff_t(spine));
  LabelSetup remove;
  remove.remove_table = true;
  EXPECT_TRUE(remove.StyleOfValue(labels, table).hidden());
  EXPECT_FALSE(LabelSetup{}.StyleOfValue(labels, table).hidden()) << "the table shows until removed";
  EXPECT_FALSE(LabelSetup{}.ChangesAnything(labels));
  EXPECT_TRUE(remove.ChangesAnything(labels));
}

// The shared CTs with a table, rendered through the frame pipeline at 96x96:
// first hits on the table (and its rim) and on the body, before and after
// the table is removed.
class TableRemoval : public ::testing::TestWithParam<const char*> {
 protected:
  struct Hits {
    int table = 0, body = 0, other = 0;
    std::vector<Vec4f> first;   // per pixel
    std::vector<bool> on_body;  // per pixel: its first hit is on the body
  };

  void SetUp() override {
    CINEVOL_REQUIRE_SHARED_DATA();
    const std::filesystem::path path = SharedData() / GetParam();
    v1::VolumeSource source;
    if (std::filesystem::is_directory(path)) {
      source.set_dicom_folder(path.string());
    } else {
      source.set_file(path.string());
    }
    image_ = std::make_shared<const Volume>(LoadVolume(source));
    table_ = FindTable(*image_);
    ASSERT_TRUE(table_.found()) << GetParam() << ": " << table_.note;
    labels_ = std::make_shared<const LabelVolume>(TableLabels(table_));
  }

  Hits Render(v1::NamedView view, bool remove) const {
    v1::Scene scene = MakePresetScene(DefaultPreset(*image_), *image_);
    // An opaque surface at the table threshold, which shows skin and table
    // alike: first hits on it do not depend on the random numbers a path
    // drew before (a translucent preset's do), so pixels compare.
    v1::TransferFunction& tf = *scene.mutable_transfer_function();
    tf.Clear();
    for (float value : {table_.table_threshold, table_.table_threshold + 1}) {
      v1::TransferFunctionPoint* p = tf.add_points();
      p->set_value(value);
      p->set_opacity(value > table_.table_threshold ? 1 : 0);
      p->mutable_diffuse()->set_r(0.8f);
      p->mutable_diffuse()->set_g(0.8f);
      p->mutable_diffuse()->set_b(0.8f);
    }
    tf.set_density_scale(20.0f);
    scene.mutable_camera()->set_view(view);
    scene.mutable_render()->set_width(96);
    scene.mutable_render()->set_height(96);
    scene.mutable_render()->set_spp(2);
    scene.mutable_labels()->set_remove_table(remove);
    ApplyDefaults(scene);
    FramePipeline pipeline(Backend::kCpu, image_, {}, labels_);
    // Every feature either way: with or without label lookups, the same
    // random numbers (render/render_scene.h), so the body's pixels compare.
    pipeline.SetRenderFeatures(kAllFeatures);
    FrameSettings settings;
    settings.denoiser.method = DenoiseMethod::kNone;
    pipeline.Update(scene, settings);
    pipeline.RenderFrame();
    Hits hits;
    hits.first = pipeline.FirstHits();
    const Vec3f extent = image_->extent_mm(), spacing = image_->spacing_mm();
    const Vec3i d = image_->dims();
    hits.on_body.assign(hits.first.size(), false);
    for (std::size_t pixel = 0; pixel < hits.first.size(); ++pixel) {
      const Vec4f h = hits.first[pixel];
      if (h.w == 0) continue;
      Vec3i v;
      for (int a = 0; a < 3; ++a) {
        const float q = (Xyz(h)[a] + 0.5f * extent[a]) / spacing[a] - 0.5f;
        v[a] = std::clamp(int(std::floor(q + 0.5f)), 0, d[a] - 1);
      }
      const std::uint8_t m = table_.voxels[(std::size_t(v.z) * d.y + v.y) * d.x + v.x];
      if (m & (kTableVoxel | kTableRimVoxel)) {
        ++hits.table;
      } else if (NearBody(v)) {
        ++hits.body;
        hits.on_body[pixel] = true;
      } else {
        ++hits.other;
      }
    }
    return hits;
  }

  // The body or within a voxel of it (its partial-volume margin).
  bool NearBody(Vec3i v) const {
    const Vec3i d = image_->dims();
    for (int z = std::max(0, v.z - 1); z <= std::min(d.z - 1, v.z + 1); ++z)
      for (int y = std::max(0, v.y - 1); y <= std::min(d.y - 1, v.y + 1); ++y)
        for (int x = std::max(0, v.x - 1); x <= std::min(d.x - 1, v.x + 1); ++x)
          if (table_.voxels[(std::size_t(z) * d.y + y) * d.x + x] & kBodyVoxel) return true;
    return false;
  }

  std::shared_ptr<const Volume> image_;
  TableMask table_;
  std::shared_ptr<const LabelVolume> labels_;
};

// From the front, the back and the left (which of them looks through the
// table depends on how the patient lay and how the file is oriented): no
// first hit on the table or its rim once it is removed, and every pixel that
// showed the body shows it where it did (within the noise of delta
// tracking), more of it where the table hid it.
TEST_P(TableRemoval, NoFirstHitOnTheTableTheBodyAsItWas) {
  const float near = 2.0f * MaxComponent(image_->spacing_mm());
  int most_table_hits = 0;
  for (v1::NamedView view : {v1::ANTERIOR, v1::POSTERIOR, v1::LEFT}) {
    const std::string name = v1::NamedView_Name(view);
    const Hits before = Render(view, false), after = Render(view, true);
    int body = 0, moved = 0;
    for (std::size_t i = 0; i < before.first.size(); ++i) {
      if (before.first[i].w == 0 || !before.on_body[i]) continue;
      ++body;
      moved += !(after.first[i].w > 0 && Length(Xyz(after.first[i]) - Xyz(before.first[i])) <= near);
    }
    std::printf("%s %s: first hits on table %d body %d -> table %d body %d; %d of %d body pixels moved over %g mm\n",
                GetParam(), name.c_str(), before.table, before.body, after.table, after.body, moved, body, near);
    EXPECT_EQ(after.table, 0) << name << ": no first hit on the table or its rim";
    EXPECT_LE(moved, body / 50) << name << ": the body's pixels show it where they did";
    EXPECT_GE(after.body, before.body - before.body / 50) << name << ": the body stays";
    EXPECT_GT(after.body, 200) << name << ": of 9216 pixels (the DICOM is a 40 mm slab)";
    most_table_hits = std::max(most_table_hits, before.table);
  }
  std::printf("%s: %s (%.2f s)\n", GetParam(), table_.note.c_str(), table_.seconds);
  EXPECT_GT(most_table_hits, 50) << "the table shows from one side at least";
}

INSTANTIATE_TEST_SUITE_P(SharedChestAndAbdomenCts, TableRemoval,
                         ::testing::Values("ct-chest-lidc2/LIDC2.nhdr", "ct-body-totalsegmentator/example_ct.nii.gz",
                                           "ct-body-totalsegmentator/example_ct_dicom"),
                         [](const auto& info) {
                           const std::string p = info.param;
                           return p.find("lidc2") != std::string::npos   ? std::string("Lidc2Chest")
                                  : p.find("dicom") != std::string::npos ? std::string("DicomAbdomen")
                                                                          : std::string("TotalSegmentatorAbdomen");
                         });

}  // namespace
}  // namespace cinevol

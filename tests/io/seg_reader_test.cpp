// DICOM SEG as a volume's segmentation (issue 57): SEGs written with DCMTK's
// dcmseg from the shared TotalSegmentator segmentation load through the
// reader cage as the same labels as the NIfTI they came from, voxel for
// voxel (binary, fractional, frames across the grid, a coarser grid placed
// nearest-neighbour, a folder); hostile SEGs are refused by name, fast,
// before their pixels are read.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <random>

#include "core/error.h"
#include "io/dicom_seg.h"
#include "io/label_volume.h"
#include "io/volume_loader.h"
#include "support/seg_writer.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

namespace fs = std::filesystem;
using testing::ScratchDir;
using testing::SegGrid;
using testing::SegOptions;
using testing::SharedData;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

// The TotalSegmentator CT's 30-slice part and its 117-label segmentation,
// loaded once per process.
class DicomSeg : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const fs::path folder = SharedData() / "ct-body-totalsegmentator";
    if (!fs::is_directory(folder)) return;
    image_ = std::make_unique<Volume>(LoadVolumeFile(folder / "example_ct_sm.nii.gz"));
    const LabelVolume nifti = LoadLabelVolume(folder / "example_seg.nii.gz", *image_);
    labels_.resize(nifti.labels.size());
    for (std::size_t i = 0; i < labels_.size(); ++i) labels_[i] = std::uint16_t(nifti.LabelOf(nifti.labels[i]));
    voxels_ = nifti.voxels;
    names_ = ParseLabelTable(ReadText(folder / "labels-total.tsv"), "labels-total.tsv");
  }
  static void TearDownTestSuite() { image_.reset(); }

  void SetUp() override {
    if (!image_) GTEST_SKIP() << "the shared data are not at " << SharedData() << "; skipping";
  }

  SegOptions Options(bool fractional = false) const {
    SegOptions options;
    options.fractional = fractional;
    options.segments = names_.rbegin()->first;
    options.names = names_;
    return options;
  }

  // The axial SEG of the whole segmentation, written once per test that asks.
  fs::path AxialSeg(bool fractional = false) {
    const fs::path file = scratch_ / (fractional ? "fractional.dcm" : "binary.dcm");
    if (!fs::exists(file)) testing::WriteSeg(file, testing::AxialGrid(*image_, labels_), Options(fractional));
    return file;
  }

  static void ExpectSameLabels(const LabelVolume& got, const std::vector<std::uint16_t>& want) {
    ASSERT_EQ(got.labels.size(), want.size());
    std::size_t differ = 0, first = 0;
    for (std::size_t i = 0; i < want.size(); ++i) {
      if (std::uint16_t(got.LabelOf(got.labels[i])) != want[i] && differ++ == 0) first = i;
    }
    EXPECT_EQ(differ, 0u) << "first at voxel " << first << ": " << got.LabelOf(got.labels[first]) << " for "
                          << want[first];
  }

  static inline std::unique_ptr<Volume> image_;
  static inline std::vector<std::uint16_t> labels_;
  static inline std::map<int, std::uint64_t> voxels_;
  static inline std::map<int, std::string> names_;
  ScratchDir scratch_;
};

TEST_F(DicomSeg, ABinarySegLoadsAsTheSameLabelsAsTheNiftiItCameFrom) {
  const fs::path file = AxialSeg();
  const auto start = std::chrono::steady_clock::now();
  const LabelVolume seg = LoadLabelVolume(file, *image_);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ExpectSameLabels(seg, labels_);
  for (const auto& [label, count] : voxels_) EXPECT_EQ(seg.voxels.count(label) ? seg.voxels.at(label) : 0, count);
  // Names and colours from the segments: every segment, present or not.
  EXPECT_EQ(seg.names, names_);
  ASSERT_EQ(seg.colors.size(), names_.size());
  for (const auto& [label, color] : seg.colors) {
    const testing::Vec3d want = testing::SegColor(label);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(color[c], want[std::size_t(c)], 1.5 / 255) << "label " << label;
  }
  const v1::LabelSet set = ToLabelSet(seg);
  EXPECT_EQ(set.names_size(), int(names_.size()) + 1);  // and 0
  EXPECT_TRUE(set.names(1).has_color());
  EXPECT_NE(seg.note.find("DICOM SEG (BINARY, 117 segments"), std::string::npos) << seg.note;
  EXPECT_NE(seg.note.find("no frame of reference"), std::string::npos) << seg.note;  // a NIfTI names none
  EXPECT_FALSE(seg.derived.empty()) << "shells, as every segmentation gets";
  RecordProperty("load_seconds", std::to_string(seconds));
  std::printf("binary SEG: %ju bytes, loaded in %.3f s\n", std::uintmax_t(fs::file_size(file)), seconds);
}

TEST_F(DicomSeg, AFractionalSegCountsPixelsAtHalfTheMaximum) {
  // 128 of 255 inside each segment, 127 outside it: exactly the threshold's two sides.
  const LabelVolume seg = LoadLabelVolume(AxialSeg(true), *image_);
  ExpectSameLabels(seg, labels_);
  EXPECT_NE(seg.note.find("FRACTIONAL"), std::string::npos) << seg.note;
}

TEST_F(DicomSeg, SagittalFramesOfTheSameGridLoadVoxelForVoxel) {
  // Frames across the volume's x axis: rows along z, columns along y.
  const Vec3i n = image_->dims();
  const Vec3f s = image_->spacing_mm();
  const auto& d = image_->metadata().direction;
  SegGrid g;
  g.columns = n.y;
  g.rows = n.z;
  g.planes = n.x;
  g.origin = image_->metadata().origin_mm;
  for (int r = 0; r < 3; ++r) {
    g.along_row[r] = d[3 * r + 1];
    g.down_column[r] = d[3 * r + 2];
    g.plane_step[r] = d[3 * r + 0] * s.x;
  }
  g.column_spacing = s.y;
  g.row_spacing = s.z;
  g.label = [&](int c, int r, int k) { return int(labels_[(std::size_t(r) * n.y + c) * n.x + k]); };
  const fs::path file = scratch_ / "sagittal.dcm";
  testing::WriteSeg(file, g, Options());
  ExpectSameLabels(LoadLabelVolume(file, *image_), labels_);
}

TEST_F(DicomSeg, ACoarserSegIsPlacedNearestNeighbour) {
  // Every second column, row and slice, at twice the spacing, the first
  // pixel's centre half a voxel on along each axis (so that no voxel centre
  // lies halfway between two pixels or planes): SEG pixel c covers voxels 2c
  // and 2c + 1 and holds voxel 2c's label.
  const Vec3i n = image_->dims();
  SegGrid g = testing::AxialGrid(*image_, labels_);
  g.columns = (n.x + 1) / 2;
  g.rows = (n.y + 1) / 2;
  g.planes = (n.z + 1) / 2;
  for (int r = 0; r < 3; ++r) {
    g.origin[r] += 0.5 * (g.along_row[r] * g.column_spacing + g.down_column[r] * g.row_spacing + g.plane_step[r]);
    g.plane_step[r] *= 2;
  }
  g.column_spacing *= 2;
  g.row_spacing *= 2;
  g.label = [&](int c, int r, int k) { return int(labels_[(std::size_t(2 * k) * n.y + 2 * r) * n.x + 2 * c]); };
  const fs::path file = scratch_ / "coarse.dcm";
  testing::WriteSeg(file, g, Options());
  std::vector<std::uint16_t> want(labels_.size(), 0);
  for (int z = 0; z < n.z; ++z) {
    for (int y = 0; y < n.y; ++y) {
      for (int x = 0; x < n.x; ++x) {
        want[(std::size_t(z) * n.y + y) * n.x + x] = labels_[(std::size_t(z & ~1) * n.y + (y & ~1)) * n.x + (x & ~1)];
      }
    }
  }
  const LabelVolume seg = LoadLabelVolume(file, *image_);
  ExpectSameLabels(seg, want);
}

TEST_F(DicomSeg, FramesOutsideTheVolumeAreCountedAndFramesBetweenItsSlicesAreNot) {
  // Twice as many planes as the volume has slices: every second one falls
  // between two slices, inside the volume, and no voxel takes it.
  const Vec3i n = image_->dims();
  SegGrid fine = testing::AxialGrid(*image_, labels_);
  fine.planes = 2 * n.z - 1;
  for (double& step : fine.plane_step) step /= 2;
  fine.label = [&](int c, int r, int k) { return int(labels_[(std::size_t(k / 2) * n.y + r) * n.x + c]); };
  const fs::path file = scratch_ / "fine.dcm";
  testing::WriteSeg(file, fine, Options());
  const LabelVolume seg = LoadLabelVolume(file, *image_);
  ExpectSameLabels(seg, labels_);
  EXPECT_EQ(seg.note.find("outside"), std::string::npos) << seg.note;

  // The upper half of the slices' frames moved a metre up: outside, and said so.
  DcmFileFormat original;
  ASSERT_TRUE(original.loadFile(AxialSeg().c_str()).good());
  const fs::path half = scratch_ / "half.dcm";
  std::size_t moved = 0;
  const double middle =
      image_->metadata().origin_mm[2] + image_->metadata().direction[8] * image_->spacing_mm().z * (n.z / 2 - 0.5);
  const bool up = image_->metadata().direction[8] > 0;
  testing::EditSeg(AxialSeg(), half, [&](DcmDataset& data) {
    DcmSequenceOfItems* frames = nullptr;
    data.findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, frames);
    for (unsigned long f = 0; f < frames->card(); ++f) {
      DcmItem* place = nullptr;
      frames->getItem(f)->findAndGetSequenceItem(DCM_PlanePositionSequence, place, 0);
      Float64 x = 0, y = 0, z = 0;
      place->findAndGetFloat64(DCM_ImagePositionPatient, x, 0);
      place->findAndGetFloat64(DCM_ImagePositionPatient, y, 1);
      place->findAndGetFloat64(DCM_ImagePositionPatient, z, 2);
      if ((z > middle) != up) continue;
      ++moved;
      place->putAndInsertString(DCM_ImagePositionPatient,
                                (testing::Ds(x) + "\\" + testing::Ds(y) + "\\" + testing::Ds(z + 1000)).c_str());
    }
  });
  ASSERT_GT(moved, 0u);
  const LabelVolume upper_gone = LoadLabelVolume(half, *image_);
  EXPECT_NE(upper_gone.note.find(fmt::format("{} of its", moved)), std::string::npos) << upper_gone.note;
  std::vector<std::uint16_t> want = labels_;
  std::fill(want.begin() + std::ptrdiff_t(std::size_t(n.z / 2) * n.y * n.x), want.end(), 0);
  ExpectSameLabels(upper_gone, want);
}

TEST_F(DicomSeg, AFolderHoldingTheSegAmongOtherFilesLoadsIt) {
  const fs::path folder = scratch_ / "folder";
  fs::create_directories(folder);
  fs::copy_file(AxialSeg(), folder / "seg.dcm");
  const auto ct = SharedData() / "ct-body-totalsegmentator/example_ct_dicom";
  fs::copy_file(fs::directory_iterator(ct)->path(), folder / "ct-slice");
  std::ofstream(folder / "README.txt") << "not DICOM\n";
  ExpectSameLabels(LoadLabelVolume(folder, *image_), labels_);

  fs::copy_file(folder / "seg.dcm", folder / "again.dcm");
  EXPECT_NE(MessageOf([&] { LoadLabelVolume(folder, *image_); }).find("2 DICOM SEGs"), std::string::npos);
  const fs::path none = scratch_ / "none";
  fs::create_directories(none);
  fs::copy_file(folder / "ct-slice", none / "ct-slice");
  EXPECT_NE(MessageOf([&] { LoadLabelVolume(none, *image_); }).find("not a DICOM SEG"), std::string::npos);
  std::ofstream(none / "README.txt") << "not DICOM\n";
  EXPECT_NE(MessageOf([&] { LoadLabelVolume(none, *image_); }).find("no DICOM SEG among its 2 files"),
            std::string::npos);
}

// Implicit VR (the reader needs DCMTK's dictionary, which it loads before
// its sandbox shuts the files) and deflated load alike; big endian is refused.
TEST_F(DicomSeg, ImplicitAndDeflatedSyntaxesLoadAlike) {
  const auto same = [](DcmDataset&) {};
  for (const E_TransferSyntax syntax : {EXS_LittleEndianImplicit, EXS_DeflatedLittleEndianExplicit}) {
    const fs::path file = scratch_ / fmt::format("syntax-{}.dcm", int(syntax));
    testing::EditSeg(AxialSeg(true), file, same, syntax);
    ExpectSameLabels(LoadLabelVolume(file, *image_), labels_);
  }
  const fs::path big = scratch_ / "big-endian.dcm";
  testing::EditSeg(AxialSeg(true), big, same, EXS_BigEndianExplicit);
  EXPECT_NE(MessageOf([&] { LoadLabelVolume(big, *image_); }).find("is not read"), std::string::npos);
}

// The image with a frame of reference, as a DICOM series has one.
Volume WithFrameOfReference(const Volume& image, const std::string& uid) {
  std::vector<float> values(image.voxel_count());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = image.ValueAtIndex(i);
  VolumeMetadata meta = image.metadata();
  meta.frame_of_reference_uid = uid;
  return Volume(image.dims(), image.spacing_mm(), std::move(values), meta);
}

TEST_F(DicomSeg, TheFrameOfReferenceMustBeTheVolumes) {
  const fs::path file = AxialSeg();
  const Volume same = WithFrameOfReference(*image_, SegOptions().frame_of_reference_uid);
  const LabelVolume seg = LoadLabelVolume(file, same);
  ExpectSameLabels(seg, labels_);
  EXPECT_EQ(seg.note.find("no frame of reference"), std::string::npos) << seg.note;
  Volume reoriented = WithFrameOfReference(*image_, SegOptions().frame_of_reference_uid);
  ApplyOrientation(reoriented, "RAS", "orientation");
  EXPECT_NE(MessageOf([&] { LoadLabelVolume(file, reoriented); }).find("read with the orientation RAS"),
            std::string::npos);
  const Volume other = WithFrameOfReference(*image_, "2.25.999");
  EXPECT_NE(MessageOf([&] {
              LoadLabelVolume(file, other);
            }).find("its frame of reference (2.25.3420000) is not the volume's (2.25.999)"),
            std::string::npos);
}

TEST_F(DicomSeg, HostileSegsAreRefusedByNameBeforeTheirPixelsAreRead) {
  const fs::path valid = AxialSeg();
  DcmFileFormat original;
  ASSERT_TRUE(original.loadFile(valid.c_str()).good());
  Sint32 frame_count = 0;
  ASSERT_TRUE(original.getDataset()->findAndGetSint32(DCM_NumberOfFrames, frame_count).good());
  struct Case {
    std::string name, expected;
    std::function<void(DcmDataset&)> edit;
  };
  const auto per_frame = [](DcmDataset& data, int f) {
    DcmItem* item = nullptr;
    data.findAndGetSequenceItem(DCM_PerFrameFunctionalGroupsSequence, item, f);
    return item;
  };
  const std::vector<Case> cases = {
      {"outside", "none of its " + std::to_string(frame_count) + " frames lies in the volume's grid",
       [&](DcmDataset& data) {
         for (int f = 0; f < frame_count; ++f) {
           DcmItem* place = nullptr;
           per_frame(data, f)->findAndGetSequenceItem(DCM_PlanePositionSequence, place, 0);
           Float64 z = 0;
           place->findAndGetFloat64(DCM_ImagePositionPatient, z, 2);
           OFString x, y;
           place->findAndGetOFString(DCM_ImagePositionPatient, x, 0);
           place->findAndGetOFString(DCM_ImagePositionPatient, y, 1);
           place->putAndInsertString(DCM_ImagePositionPatient,
                                     (x + "\\" + y + "\\" + testing::Ds(z + 10000).c_str()).c_str());
         }
       }},
      {"segments", "10000 segments; cinevol reads at most 1024",
       [](DcmDataset& data) {
         DcmSequenceOfItems* segments = nullptr;
         data.findAndGetSequence(DCM_SegmentSequence, segments);
         for (int s = int(segments->card()) + 1; s <= 10000; ++s) {
           auto* copy = new DcmItem(*segments->getItem(0));
           copy->putAndInsertUint16(DCM_SegmentNumber, Uint16(s));
           segments->append(copy);
         }
       }},
      {"more frames",
       fmt::format("Number of Frames is {} but its Per-frame Functional Groups Sequence holds {} items",
                   frame_count + 1, frame_count),
       [&](DcmDataset& data) { data.putAndInsertString(DCM_NumberOfFrames, std::to_string(frame_count + 1).c_str()); }},
      {"fewer frames", "its Pixel Data hold",
       [&](DcmDataset& data) {
         data.putAndInsertString(DCM_NumberOfFrames, std::to_string(frame_count - 1).c_str());
         DcmSequenceOfItems* frames = nullptr;
         data.findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, frames);
         delete frames->remove(frames->card() - 1);
       }},
      {"huge", "exceeds this server's limit",
       [](DcmDataset& data) {
         data.putAndInsertUint16(DCM_Rows, 65535);
         data.putAndInsertUint16(DCM_Columns, 65535);
         data.putAndInsertString(DCM_NumberOfFrames, "1000000");
       }},
      {"unknown segment", "frame 1 names segment 999, which its Segment Sequence does not hold",
       [&](DcmDataset& data) {
         DcmItem* id = nullptr;
         per_frame(data, 0)->findAndGetSequenceItem(DCM_SegmentIdentificationSequence, id, 0);
         id->putAndInsertUint16(DCM_ReferencedSegmentNumber, 999);
       }},
      {"no frame of reference", "names no Frame of Reference UID",
       [](DcmDataset& data) { delete data.remove(DCM_FrameOfReferenceUID); }},
      {"labelmap", "Segmentation Type 'LABELMAP'",
       [](DcmDataset& data) { data.putAndInsertString(DCM_SegmentationType, "LABELMAP"); }},
  };
  for (const Case& c : cases) {
    const fs::path file = scratch_ / (c.name + ".dcm");
    testing::EditSeg(valid, file, c.edit);
    const auto start = std::chrono::steady_clock::now();
    const std::string message = MessageOf([&] { LoadLabelVolume(file, *image_); });
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.name << ": " << message;
    EXPECT_NE(message.find(file.string()), std::string::npos) << c.name << ": names the file: " << message;
    EXPECT_LT(seconds, 10.0) << c.name;
    std::printf("%-22s %.3f s  %s\n", c.name.c_str(), seconds, message.c_str());
  }
  // Not a SEG at all.
  const fs::path ct = *fs::directory_iterator(SharedData() / "ct-body-totalsegmentator/example_ct_dicom");
  EXPECT_NE(MessageOf([&] { LoadSegmentation(ct, *image_); }).find("not a DICOM SEG: its SOP Class UID"),
            std::string::npos);
}

// Random bytes changed and files cut short: every load ends, in labels or
// an error naming the file; none takes the test process (the parent) down.
TEST(DicomSegMutations, MutatedSegsEndInLabelsOrAnErrorNamingTheFile) {
  ScratchDir scratch;
  const Vec3i n{24, 20, 6};
  VolumeMetadata meta;
  meta.source = "grid";
  meta.origin_mm = {-10, 20, 30};
  const Volume image(n, {1.0f, 1.5f, 2.0f}, std::vector<float>(std::size_t(n.x) * n.y * n.z, 0.0f), meta);
  std::vector<std::uint16_t> labels(std::size_t(n.x) * n.y * n.z);
  for (std::size_t i = 0; i < labels.size(); ++i) labels[i] = std::uint16_t((i / 7) % 4);
  SegOptions options;
  options.segments = 3;
  const fs::path valid = scratch / "valid.dcm";
  testing::WriteSeg(valid, testing::AxialGrid(image, labels), options);
  const std::string bytes = ReadText(valid);
  std::mt19937 random(57);
  std::map<std::string, int> outcomes;
  // CINEVOL_SEG_MUTATIONS asks for more (by hand: 2000 in docs/pacs.md).
  const char* asked = std::getenv("CINEVOL_SEG_MUTATIONS");
  const int count = asked ? std::max(1, std::atoi(asked)) : 120;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < count; ++i) {
    std::string mutated = bytes;
    if (i % 6 == 5) {
      mutated.resize(132 + random() % (mutated.size() - 132));
    } else {
      for (int k = 0; k < 1 + i % 4; ++k) mutated[132 + random() % (mutated.size() - 132)] = char(random());
    }
    const fs::path file = scratch / fmt::format("mutated-{}.dcm", i);
    std::ofstream(file, std::ios::binary) << mutated;
    try {
      const LabelVolume seg = LoadLabelVolume(file, image);
      ++outcomes["labels"];
    } catch (const std::exception& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(file.string()), std::string::npos) << message;
      ++outcomes[message.find("reader stopped") != std::string::npos ? "reader crashed" : "refused"];
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%d mutated SEGs in %.1f s:", count, seconds);
  for (const auto& [outcome, count] : outcomes) std::printf(" %s %d", outcome.c_str(), count);
  std::printf("\n");
  EXPECT_EQ(outcomes["labels"] + outcomes["refused"] + outcomes["reader crashed"], count);
}

TEST(DicomSegColours, CieLabReadsBackAsDcmtkWritesIt) {
  for (const testing::Vec3d rgb : {testing::Vec3d{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}, {0.2, 0.5, 0.7}}) {
    double lab[3];
    IODCIELabUtil::rgb2DicomLab(lab[0], lab[1], lab[2], rgb[0], rgb[1], rgb[2]);
    const Vec3f back = DicomLabToRgb(
        {std::uint16_t(std::lround(lab[0])), std::uint16_t(std::lround(lab[1])), std::uint16_t(std::lround(lab[2]))});
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back[c], rgb[std::size_t(c)], 1.0 / 255) << rgb[0] << rgb[1] << rgb[2];
  }
}

}  // namespace
}  // namespace cinevol

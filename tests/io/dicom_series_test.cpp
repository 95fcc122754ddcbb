// DICOM folders built from the real slices: several series, missing and
// duplicate slices, gantry tilt (resampled), truncated files, empty folders.
#include <gdcmAttribute.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "core/error.h"
#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
using testing::SharedData;
namespace fs = std::filesystem;

// The DICOM files of a folder (the data sets keep a README beside them).
std::vector<fs::path> SortedFiles(const fs::path& folder) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.path().filename() != "README.txt") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

fs::path MrFolder() { return SharedData() / "mr-chest-dicom-seg3d"; }
fs::path CtFolder() { return SharedData() / "ct-body-totalsegmentator/example_ct_dicom"; }

// Copies `files` into `to`, writable (the shared data are read-only).
void CopyAll(const std::vector<fs::path>& files, const fs::path& to) {
  for (const auto& f : files) {
    fs::copy_file(f, to / f.filename());
    fs::permissions(to / f.filename(), fs::perms::owner_write, fs::perm_options::add);
  }
}

std::string LoadError(const fs::path& folder) {
  try {
    LoadDicomSeries(folder);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded without error)";
}

// Rewrites one file's header in place with `edit`.
template <class Edit>
void EditHeader(const fs::path& file, Edit edit) {
  gdcm::Reader reader;
  reader.SetFileName(file.c_str());
  ASSERT_TRUE(reader.Read()) << file;
  edit(reader.GetFile().GetDataSet());
  gdcm::Writer writer;
  writer.SetFile(reader.GetFile());
  writer.SetFileName(file.c_str());
  ASSERT_TRUE(writer.Write()) << file;
}

void ShiftPosition(const fs::path& file, double dy) {
  EditHeader(file, [&](gdcm::DataSet& ds) {
    gdcm::Attribute<0x0020, 0x0032> ipp;
    ipp.Set(ds);
    ipp.SetValue(ipp.GetValue(1) + dy, 1);
    ds.Replace(ipp.GetAsDataElement());
  });
}

void SetSeriesUid(const fs::path& file, const std::string& uid) {
  EditHeader(file, [&](gdcm::DataSet& ds) {
    gdcm::Attribute<0x0020, 0x000e> a;
    a.SetValue(uid);
    ds.Replace(a.GetAsDataElement());
  });
}

TEST(DicomSeries, EmptyFolderIsRefused) {
  ScratchDir dir;
  EXPECT_NE(LoadError(dir.path()).find("no DICOM files"), std::string::npos);
}

TEST(DicomSeries, FolderWithoutDicomIsRefused) {
  ScratchDir dir;
  std::ofstream(dir / "readme.txt") << "not an image";
  const std::string error = LoadError(dir.path());
  EXPECT_NE(error.find("no DICOM files"), std::string::npos) << error;
  EXPECT_NE(error.find("1 files looked at"), std::string::npos) << error;
}

TEST(DicomSeries, SeveralSeriesLoadTheLargest) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  CopyAll(SortedFiles(MrFolder()), dir.path());
  auto ct = SortedFiles(CtFolder());
  ct.resize(5);
  CopyAll(ct, dir.path());
  const auto series = ListDicomSeries(dir.path());
  ASSERT_EQ(series.size(), 2u);
  EXPECT_EQ(series[0].file_count, 20u);
  EXPECT_EQ(series[0].modality, "MR");
  EXPECT_EQ(series[1].modality, "CT");
  const Volume v = LoadDicomSeries(dir.path());
  EXPECT_EQ(v.dims(), (Vec3i{640, 640, 20}));
  EXPECT_EQ(v.metadata().modality, "MR");
}

TEST(DicomSeries, SeriesUidChoosesASeries) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  auto files = SortedFiles(MrFolder());
  CopyAll(files, dir.path());
  // Split the (anonymised, UID-less) series in two: 12 slices and 8.
  const auto copies = SortedFiles(dir.path());
  for (std::size_t i = 0; i < copies.size(); ++i) SetSeriesUid(copies[i], i < 12 ? "1.2.3.12" : "1.2.3.8");
  EXPECT_EQ(LoadDicomSeries(dir.path()).dims().z, 12);
  EXPECT_EQ(LoadDicomSeries(dir.path(), "1.2.3.8").dims().z, 8);
  try {
    LoadDicomSeries(dir.path(), "1.2.3.does.not.exist");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("1.2.3.12"), std::string::npos) << "lists the others";
  }
}

TEST(DicomSeries, MissingSliceIsRefused) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  auto files = SortedFiles(MrFolder());
  files.erase(files.begin() + 7);
  CopyAll(files, dir.path());
  const std::string error = LoadError(dir.path());
  EXPECT_NE(error.find("uneven slice spacing"), std::string::npos) << error;
  EXPECT_NE(error.find("5.000 mm"), std::string::npos) << "names the gap: " << error;
}

// Asked to, a series with missing slices loads resampled onto an even grid
// at its smallest gap: the slices it has keep their values, a missing one is
// the mean of its neighbours, and a note names the largest gap.
TEST(DicomSeries, UnevenGapsAreResampledWhenAsked) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  auto files = SortedFiles(MrFolder());
  files.erase(files.begin() + 12, files.begin() + 14);  // 7.5 mm between slices 11 and 14
  files.erase(files.begin() + 5);                       // 5 mm between slices 4 and 6
  CopyAll(files, dir.path());
  EXPECT_NE(LoadError(dir.path()).find("(--resample-uneven)"), std::string::npos) << LoadError(dir.path());
  LoadPolicy asked;
  asked.resample_uneven = true;
  const Volume even = LoadDicomSeries(dir.path(), {}, asked);
  const Volume original = LoadDicomSeries(MrFolder());
  ASSERT_EQ(even.dims(), original.dims()) << "the whole span at the smallest gap: 20 slices again";
  EXPECT_FLOAT_EQ(even.spacing_mm().z, original.spacing_mm().z);
  ASSERT_FALSE(even.metadata().notes.empty());
  EXPECT_NE(even.metadata().notes.back().find("gaps run to 7.5 mm"), std::string::npos) << even.metadata().notes.back();
  const Vec3i d = even.dims();
  for (int x = 0; x < d.x; x += 37) {
    for (int y = 0; y < d.y; y += 41) {
      EXPECT_FLOAT_EQ(even.Value(x, y, 4), original.Value(x, y, 4));
      EXPECT_FLOAT_EQ(even.Value(x, y, 14), original.Value(x, y, 14));
      EXPECT_NEAR(even.Value(x, y, 5), 0.5f * (original.Value(x, y, 4) + original.Value(x, y, 6)), 1e-3f);
      EXPECT_NEAR(even.Value(x, y, 12), (2 * original.Value(x, y, 11) + original.Value(x, y, 14)) / 3, 1e-2f);
    }
  }
}

TEST(DicomSeries, FilesInAnyOrderAreSortedByPosition) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  auto files = SortedFiles(MrFolder());
  std::reverse(files.begin(), files.end());
  for (std::size_t i = 0; i < files.size(); ++i) {
    fs::copy_file(files[i], dir / ("slice" + std::to_string(100 + i) + ".dcm"));
  }
  const Volume shuffled = LoadDicomSeries(dir.path());
  const Volume original = LoadDicomSeries(MrFolder());
  ASSERT_EQ(shuffled.dims(), original.dims());
  EXPECT_EQ(shuffled.Value(320, 320, 3), original.Value(320, 320, 3));
  EXPECT_EQ(shuffled.Value(100, 400, 17), original.Value(100, 400, 17));
}

TEST(DicomSeries, DuplicatePositionsAreRefused) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto files = SortedFiles(MrFolder());
  CopyAll(files, dir.path());
  fs::copy_file(files[3], dir / "copy-of-slice.dcm");
  EXPECT_NE(LoadError(dir.path()).find("same position"), std::string::npos);
}

// Mean absolute difference of slice `k` of `a`, moved `shift` voxels along
// y, and the same slice of `b`, over the voxels both hold.
double SliceDifference(const Volume& a, const Volume& b, int k, int shift) {
  double sum = 0;
  int n = 0;
  for (int y = std::max(0, -shift); y < a.dims().y && y + shift < a.dims().y; ++y) {
    if (y + shift < 0) continue;
    for (int x = 0; x < a.dims().x; ++x) {
      sum += std::abs(a.Value(x, y + shift, k) - b.Value(x, y, k));
      ++n;
    }
  }
  return sum / std::max(n, 1);
}

TEST(DicomSeries, GantryTiltIsResampledOntoARegularGrid) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto files = SortedFiles(MrFolder());
  CopyAll(files, dir.path());
  // Shear the stack by 10 degrees: each slice 2.5 mm further moves tan(10) * 2.5 mm in y.
  const double per_slice_mm = std::tan(10.0 * M_PI / 180.0) * 2.5;
  std::vector<fs::path> copies = SortedFiles(dir.path());
  for (std::size_t i = 0; i < copies.size(); ++i) ShiftPosition(copies[i], per_slice_mm * double(i));
  const Volume original = LoadDicomSeries(MrFolder());
  const Volume tilted = LoadDicomSeries(dir.path());
  ASSERT_EQ(tilted.dims(), original.dims());
  ASSERT_FALSE(tilted.metadata().notes.empty());
  EXPECT_NE(tilted.metadata().notes[0].find("gantry tilt of 10.0 degrees"), std::string::npos)
      << tilted.metadata().notes[0];
  // Slice k of the regular grid is the sheared slice k moved back by its shift
  // along the image's columns (patient y): the same anatomy at the same place.
  const int k = 10;
  const double col_y = original.metadata().direction[3 * 1 + 1];  // patient y of index axis y
  const int shift = int(std::lround(per_slice_mm * k * col_y / original.spacing_mm().y));
  ASSERT_GE(std::abs(shift), 5);
  const double moved = SliceDifference(tilted, original, k, shift);
  const double unmoved = SliceDifference(tilted, original, k, 0);
  EXPECT_LT(moved, 0.25 * unmoved) << "moved " << moved << ", unmoved " << unmoved;
}

TEST(DicomSeries, TruncatedSliceIsAClearError) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  CopyAll(SortedFiles(CtFolder()), dir.path());  // JPEG 2000 compressed
  const fs::path victim = SortedFiles(dir.path())[10];
  fs::resize_file(victim, fs::file_size(victim) / 2);
  const std::string error = LoadError(dir.path());
  EXPECT_NE(error.find(dir.path().string()), std::string::npos) << error;
}

// What a radiologist's corners show comes out of the cage with the voxels.
TEST(DicomSeries, IdentityAndStoredWindowComeWithTheVolume) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const Volume v = LoadDicomSeries(MrFolder());
  const PatientIdentity& id = v.metadata().identity;
  EXPECT_EQ(id.patient_name, "My Patient Name");
  EXPECT_EQ(id.patient_id, "123456789");
  EXPECT_EQ(id.study_date, "20091203");
  EXPECT_EQ(id.study_description, "My Study Name");
  EXPECT_EQ(id.series_description, "My Special Series For Testing");
  ASSERT_TRUE(v.metadata().stored_window);
  EXPECT_EQ(v.metadata().stored_window->center, 268);
  EXPECT_EQ(v.metadata().stored_window->width, 622);
}

// Fields from a hostile file: a name that would forge a second line or is
// not UTF-8 arrives as one escaped line; a window DICOM forbids is none.
TEST(DicomSeries, HostileIdentityAndWindowAreTamed) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  CopyAll(SortedFiles(MrFolder()), dir.path());
  for (const fs::path& f : SortedFiles(dir.path())) {
    EditHeader(f, [](gdcm::DataSet& ds) {
      const auto set = [&](gdcm::Tag tag, gdcm::VR vr, const std::string& value) {
        gdcm::DataElement element(tag);
        element.SetVR(vr);
        element.SetByteValue(value.data(), std::uint32_t(value.size()));
        ds.Replace(element);
      };
      set({0x0010, 0x0010}, gdcm::VR::PN, "M\xfcller^Hans\nFORGED");
      set({0x0028, 0x1051}, gdcm::VR::DS, "0.5 ");  // below DICOM's minimum of 1
    });
  }
  const Volume v = LoadDicomSeries(dir.path());
  const std::string& name = v.metadata().identity.patient_name;
  EXPECT_EQ(name.find('\n'), std::string::npos) << name;
  EXPECT_NE(name.find("FORGED"), std::string::npos) << name;
  EXPECT_NE(name.find("\\xfc"), std::string::npos) << name;  // Latin-1's u-umlaut, escaped
  EXPECT_FALSE(v.metadata().stored_window);
}

// Files without the fields (NIfTI, phantoms) carry none.
TEST(DicomSeries, OtherFilesCarryNoIdentity) {
  const Volume v = LoadVolume(ParseVolumeSpec("phantom:head"));
  EXPECT_TRUE(v.metadata().identity.patient_name.empty());
  EXPECT_FALSE(v.metadata().stored_window);
}

}  // namespace
}  // namespace cinevol

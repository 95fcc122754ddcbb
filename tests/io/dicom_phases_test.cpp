// DICOM series of several phases (4D: cardiac cine, dynamic series): files
// repeating each slice position are read as a time series, each position's
// files ordered by Temporal Position Identifier, else Trigger Time, else
// Instance Number; the frames of an enhanced multi-frame file likewise, by
// their functional groups. Time series made from the shared MR's slices (a
// cine in the layout scanners write, an enhanced MR, and variations), with
// their refusals.
#include <gdcmAttribute.h>
#include <gdcmItem.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
using testing::SharedData;
namespace fs = std::filesystem;

fs::path MrFolder() { return SharedData() / "mr-chest-dicom-seg3d"; }

VolumeSeries LoadSeries(const fs::path& folder, const LoadPolicy& policy = {}) {
  v1::VolumeSource source;
  source.set_dicom_folder(folder.string());
  return LoadVolumeSeries(source, {}, policy);
}

std::string SeriesError(const fs::path& folder, const LoadPolicy& policy = {}) {
  try {
    LoadSeries(folder, policy);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(loaded without error)";
}

std::unique_ptr<gdcm::Reader> ReadDicom(const fs::path& file) {
  auto reader = std::make_unique<gdcm::Reader>();
  reader->SetFileName(file.c_str());
  if (!reader->Read()) throw std::runtime_error("cannot read " + file.string());
  return reader;
}

void WriteDicom(gdcm::Reader& reader, const fs::path& file) {
  gdcm::Writer writer;
  writer.SetFile(reader.GetFile());
  writer.SetFileName(file.c_str());
  if (!writer.Write()) throw std::runtime_error("cannot write " + file.string());
}

// Rewrites one file's header in place with `edit`.
template <class Edit>
void EditHeader(const fs::path& file, Edit edit) {
  const auto reader = ReadDicom(file);
  edit(reader->GetFile().GetDataSet());
  WriteDicom(*reader, file);
}

void SetTriggerTime(gdcm::DataSet& ds, double ms) {
  gdcm::Attribute<0x0018, 0x1060> a;
  a.SetValue(ms);
  ds.Replace(a.GetAsDataElement());
}

void SetInstanceNumber(gdcm::DataSet& ds, int n) {
  gdcm::Attribute<0x0020, 0x0013> a;
  a.SetValue(n);
  ds.Replace(a.GetAsDataElement());
}

void SetTemporalPosition(gdcm::DataSet& ds, int n) {
  gdcm::Attribute<0x0020, 0x0100> a;
  a.SetValue(n);
  ds.Replace(a.GetAsDataElement());
}

// A file's position along its slices' normal (mm).
double AlongNormal(const gdcm::DataSet& ds) {
  gdcm::Attribute<0x0020, 0x0037> iop;
  iop.Set(ds);
  gdcm::Attribute<0x0020, 0x0032> ipp;
  ipp.Set(ds);
  const double r[3] = {iop.GetValue(0), iop.GetValue(1), iop.GetValue(2)};
  const double c[3] = {iop.GetValue(3), iop.GetValue(4), iop.GetValue(5)};
  const double n[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
  return ipp.GetValue(0) * n[0] + ipp.GetValue(1) * n[1] + ipp.GetValue(2) * n[2];
}

// The MR's files in the order of the loaded volume's slices (along the normal).
std::vector<fs::path> MrSlicesInOrder() {
  std::vector<std::pair<double, fs::path>> at;
  for (const auto& e : fs::directory_iterator(MrFolder())) {
    if (e.path().extension() != ".dcm") continue;
    at.push_back({AlongNormal(ReadDicom(e.path())->GetFile().GetDataSet()), e.path()});
  }
  std::sort(at.begin(), at.end());
  std::vector<fs::path> out;
  for (const auto& [along, path] : at) out.push_back(path);
  return out;
}

// A time series of 3 phases x `positions` slices written into `dir` from the
// MR's slices: file (p, i), phase p at position i, holds MR slice
// i + positions * p moved to MR slice i's position, with Trigger Time
// kTrigger[p] * (1 + 0.1 i) ms (each position its own heart rate, as a cine's
// breath holds), Instance Number 1 + positions * p + i (p's order, which the
// trigger times contradict) and a shuffled file name. `edit` changes each
// file's header last. Returns the paths, [p][i].
constexpr std::array<double, 3> kTrigger{300, 100, 200};  // phase order by trigger time: p = 1, 2, 0
constexpr std::array<int, 3> kByTrigger{1, 2, 0};

template <class Edit>
std::vector<std::vector<fs::path>> WriteTimeSeries(const fs::path& dir, int positions, Edit edit) {
  const std::vector<fs::path> mr = MrSlicesInOrder();
  std::vector<int> names(std::size_t(3 * positions));
  std::iota(names.begin(), names.end(), 100);
  std::shuffle(names.begin(), names.end(), std::mt19937(59));
  std::vector<std::vector<fs::path>> out(3);
  for (int i = 0; i < positions; ++i) {
    const gdcm::DataElement position =
        ReadDicom(mr[std::size_t(i)])->GetFile().GetDataSet().GetDataElement(gdcm::Tag(0x0020, 0x0032));
    for (int p = 0; p < 3; ++p) {
      const auto reader = ReadDicom(mr[std::size_t(i + positions * p)]);
      gdcm::DataSet& ds = reader->GetFile().GetDataSet();
      ds.Replace(position);
      SetTriggerTime(ds, kTrigger[std::size_t(p)] * (1 + 0.1 * i));
      SetInstanceNumber(ds, 1 + positions * p + i);
      edit(ds, p, i);
      const fs::path file = dir / ("im" + std::to_string(names[std::size_t(p * positions + i)]) + ".dcm");
      WriteDicom(*reader, file);
      out[std::size_t(p)].push_back(file);
    }
  }
  return out;
}

std::vector<std::vector<fs::path>> WriteTimeSeries(const fs::path& dir, int positions) {
  return WriteTimeSeries(dir, positions, [](gdcm::DataSet&, int, int) {});
}

// Whether phase `phase` of `series` holds, at slice i, MR slice i + positions
// * p (sampled every 7th voxel).
void ExpectPhaseHolds(const VolumeSeries& series, std::size_t phase, int p, const Volume& mr) {
  const Volume& v = series.phases[phase];
  const int positions = v.dims().z;
  int differing = 0;
  for (int z = 0; z < positions; ++z) {
    for (int y = 0; y < v.dims().y; y += 7) {
      for (int x = 0; x < v.dims().x; x += 7) differing += v.Value(x, y, z) != mr.Value(x, y, z + positions * p);
    }
  }
  EXPECT_EQ(differing, 0) << "phase " << phase << " should hold the copies of phase p = " << p;
}

// ------------------------------------------------------- a cine as scanners write it

// The layout of a cardiac cine as MR scanners write it (the Sunnybrook cine,
// bench/time-series-run.sh, has it): each file its own Frame of Reference
// UID, Instance Numbers running phase-fastest, Trigger Times and no Temporal
// Position Identifier. Here 10 phases x 2 positions from the MR's 20 slices:
// file (p, i) holds MR slice i + 2 p at MR slice i's position, Trigger Time
// 40 p + 3 i ms, Instance Number 10 i + p + 1.
constexpr int kCinePhases = 10;

void WriteCine(const fs::path& dir) {
  const std::vector<fs::path> mr = MrSlicesInOrder();
  for (int i = 0; i < 2; ++i) {
    const gdcm::DataElement position =
        ReadDicom(mr[std::size_t(i)])->GetFile().GetDataSet().GetDataElement(gdcm::Tag(0x0020, 0x0032));
    for (int p = 0; p < kCinePhases; ++p) {
      const auto reader = ReadDicom(mr[std::size_t(i + 2 * p)]);
      gdcm::DataSet& ds = reader->GetFile().GetDataSet();
      ds.Replace(position);
      SetTriggerTime(ds, 40 * p + 3 * i);
      const int n = kCinePhases * i + p + 1;
      SetInstanceNumber(ds, n);
      gdcm::Attribute<0x0020, 0x0052> frame_of_reference;
      frame_of_reference.SetValue("1.2.826.0.1.3680043.2.1143.59." + std::to_string(n));
      ds.Replace(frame_of_reference.GetAsDataElement());
      WriteDicom(*reader, dir / (std::to_string(n) + ".dcm"));
    }
  }
}

// A cine of kCinePhases phases as WriteCine's: phase p holds MR slices 2 p
// and 2 p + 1, 40 ms after the one before.
void ExpectTheCine(const VolumeSeries& cine, const Volume& mr) {
  ASSERT_EQ(cine.phases.size(), std::size_t(kCinePhases));
  ASSERT_EQ(cine.seconds.size(), std::size_t(kCinePhases));
  for (std::size_t p = 0; p < cine.phases.size(); ++p) {
    ASSERT_EQ(cine.phases[p].dims(), (Vec3i{640, 640, 2}));
    ExpectPhaseHolds(cine, p, int(p), mr);
    EXPECT_NEAR(cine.seconds[p], 0.040 * double(p), 1e-9);
  }
}

// Phase p is every position's p-th file by Trigger Time; its time the mean of
// its files' from phase 0's; one Frame of Reference for all, as for one phase;
// each phase as its files read alone.
TEST(DicomPhases, ACineOfTenPhasesLoadsWithTheirTimes) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteCine(dir.path());
  const VolumeSeries cine = LoadSeries(dir.path());
  const Volume mr = LoadDicomSeries(MrFolder());
  ASSERT_NO_FATAL_FAILURE(ExpectTheCine(cine, mr));
  for (const Volume& phase : cine.phases) {
    EXPECT_EQ(phase.metadata().origin_mm, cine.phases[0].metadata().origin_mm);
    EXPECT_EQ(phase.metadata().frame_of_reference_uid, cine.phases[0].metadata().frame_of_reference_uid);
  }
  EXPECT_FALSE(cine.phases[0].metadata().frame_of_reference_uid.empty()) << "one file's, as for one phase";

  for (int p : {0, 9}) {
    const fs::path alone = dir / ("phase" + std::to_string(p));
    fs::create_directory(alone);
    for (int i = 0; i < 2; ++i) {
      const std::string name = std::to_string(kCinePhases * i + p + 1) + ".dcm";
      fs::copy_file(dir / name, alone / name);
    }
    const Volume single = LoadDicomSeries(alone);
    const Volume& phase = cine.phases[std::size_t(p)];
    ASSERT_EQ(single.dims(), phase.dims());
    EXPECT_EQ(single.metadata().origin_mm, phase.metadata().origin_mm);
    EXPECT_EQ(single.metadata().direction, phase.metadata().direction);
    std::size_t differing = 0;
    for (std::size_t k = 0; k < phase.voxel_count(); k += 5)
      differing += single.ValueAtIndex(k) != phase.ValueAtIndex(k);
    EXPECT_EQ(differing, 0u) << "phase " << p;
  }
}

// -------------------------------------------------- time series from the MR

// Phases follow Trigger Time, whatever the file names and Instance Numbers
// say; each phase's time is the mean of its positions' trigger times.
TEST(DicomPhases, PhasesFollowTriggerTime) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteTimeSeries(dir.path(), 4);
  const VolumeSeries series = LoadSeries(dir.path());
  ASSERT_EQ(series.phases.size(), 3u);
  const Volume mr = LoadDicomSeries(MrFolder());
  for (std::size_t k = 0; k < 3; ++k) {
    ASSERT_EQ(series.phases[k].dims(), (Vec3i{640, 640, 4}));
    ExpectPhaseHolds(series, k, kByTrigger[k], mr);
  }
  EXPECT_EQ(series.phases[0].metadata().origin_mm, mr.metadata().origin_mm);
  EXPECT_FLOAT_EQ(series.phases[0].spacing_mm().z, mr.spacing_mm().z);
  // Trigger times kTrigger[p] * (1 + 0.1 i): their mean over i = 0..3 is kTrigger[p] * 1.15.
  ASSERT_EQ(series.seconds.size(), 3u);
  EXPECT_NEAR(series.seconds[0], 0, 1e-12);
  EXPECT_NEAR(series.seconds[1], 0.115, 1e-9);
  EXPECT_NEAR(series.seconds[2], 0.230, 1e-9);
}

// The Temporal Position Identifier orders the phases before the Trigger
// Time; trigger times that then do not rise phase by phase give no times.
TEST(DicomPhases, TemporalPositionIdentifierComesFirst) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  constexpr std::array<int, 3> kTemporal{2, 3, 1};  // order: p = 2, 0, 1
  WriteTimeSeries(dir.path(), 4,
                  [&](gdcm::DataSet& ds, int p, int) { SetTemporalPosition(ds, kTemporal[std::size_t(p)]); });
  const VolumeSeries series = LoadSeries(dir.path());
  ASSERT_EQ(series.phases.size(), 3u);
  const Volume mr = LoadDicomSeries(MrFolder());
  ExpectPhaseHolds(series, 0, 2, mr);
  ExpectPhaseHolds(series, 1, 0, mr);
  ExpectPhaseHolds(series, 2, 1, mr);
  EXPECT_TRUE(series.seconds.empty()) << "trigger times 230, 345, 115 ms do not rise";
  const std::vector<std::string>& notes = series.phases[0].metadata().notes;
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.back().find("ordered by Temporal Position Identifier"), std::string::npos) << notes.back();
}

// Without Trigger Times the Instance Number orders them, and they have no times.
TEST(DicomPhases, InstanceNumberOrdersWithoutTriggerTimes) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  constexpr std::array<int, 3> kRank{1, 2, 0};  // Instance Numbers put p = 2 first, then 0, then 1
  WriteTimeSeries(dir.path(), 4, [&](gdcm::DataSet& ds, int p, int i) {
    ds.Remove(gdcm::Tag(0x0018, 0x1060));
    SetInstanceNumber(ds, 1 + 4 * kRank[std::size_t(p)] + i);
  });
  const VolumeSeries series = LoadSeries(dir.path());
  ASSERT_EQ(series.phases.size(), 3u);
  const Volume mr = LoadDicomSeries(MrFolder());
  ExpectPhaseHolds(series, 0, 2, mr);
  ExpectPhaseHolds(series, 1, 0, mr);
  ExpectPhaseHolds(series, 2, 1, mr);
  EXPECT_TRUE(series.seconds.empty());
  ASSERT_FALSE(series.phases[0].metadata().notes.empty());
  EXPECT_NE(series.phases[0].metadata().notes.back().find("ordered by Instance Number"), std::string::npos)
      << series.phases[0].metadata().notes.back();
}

// A time series with gaps that differ (a position missing in every phase)
// is resampled per phase onto the first phase's even grid, when asked.
TEST(DicomPhases, UnevenGapsAreResampledInEveryPhase) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto files = WriteTimeSeries(dir.path(), 5);
  for (int p = 0; p < 3; ++p) fs::remove(files[std::size_t(p)][2]);  // positions 0, 1, 3, 4 left
  EXPECT_NE(SeriesError(dir.path()).find("uneven slice spacing"), std::string::npos) << SeriesError(dir.path());
  LoadPolicy asked;
  asked.resample_uneven = true;
  const VolumeSeries series = LoadSeries(dir.path(), asked);
  ASSERT_EQ(series.phases.size(), 3u);
  const Volume mr = LoadDicomSeries(MrFolder());
  for (std::size_t k = 0; k < 3; ++k) {
    const Volume& v = series.phases[k];
    ASSERT_EQ(v.dims(), (Vec3i{640, 640, 5}));
    const int first = 5 * kByTrigger[k];  // the MR slice at position 0 in this phase
    for (int y = 0; y < 640; y += 53) {
      for (int x = 0; x < 640; x += 59) {
        EXPECT_NEAR(v.Value(x, y, 1), mr.Value(x, y, first + 1), 1e-2f);
        EXPECT_NEAR(v.Value(x, y, 3), mr.Value(x, y, first + 3), 1e-2f);
        EXPECT_NEAR(v.Value(x, y, 2), 0.5f * (mr.Value(x, y, first + 1) + mr.Value(x, y, first + 3)), 1e-3f);
      }
    }
  }
}

// A gantry-tilted time series: each phase shifted onto the regular grid as
// its own slices alone are.
TEST(DicomPhases, GantryTiltIsResampledInEveryPhase) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  fs::create_directory(dir / "series");
  const double per_slice_mm = std::tan(10.0 * M_PI / 180.0) * 2.5;  // 10 degrees over the MR's 2.5 mm gaps
  const auto files = WriteTimeSeries(dir / "series", 4, [&](gdcm::DataSet& ds, int, int i) {
    gdcm::Attribute<0x0020, 0x0032> ipp;
    ipp.Set(ds);
    ipp.SetValue(ipp.GetValue(1) + per_slice_mm * i, 1);
    ds.Replace(ipp.GetAsDataElement());
  });
  const VolumeSeries series = LoadSeries(dir / "series");
  ASSERT_EQ(series.phases.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    const Volume& v = series.phases[k];
    ASSERT_FALSE(v.metadata().notes.empty());
    EXPECT_NE(v.metadata().notes[0].find("gantry tilt of 10.0 degrees"), std::string::npos) << v.metadata().notes[0];
    const fs::path alone = dir / ("phase" + std::to_string(k));
    fs::create_directory(alone);
    for (const fs::path& f : files[std::size_t(kByTrigger[k])]) fs::copy_file(f, alone / f.filename());
    const Volume single = LoadDicomSeries(alone);
    ASSERT_EQ(single.dims(), v.dims());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < v.voxel_count(); i += 3) differing += single.ValueAtIndex(i) != v.ValueAtIndex(i);
    EXPECT_EQ(differing, 0u) << "phase " << k;
  }
}

// ------------------------------------------------------------------ refusals

// Where one volume is wanted, a time series is refused (not its first phase).
TEST(DicomPhases, ATimeSeriesIsNoSingleVolume) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteTimeSeries(dir.path(), 4);
  try {
    LoadDicomSeries(dir.path());
    ADD_FAILURE() << "a time series loaded as one volume";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a time series of 3 phases, where one volume is read"), std::string::npos)
        << e.what();
  }
}

// The voxel limit counts every phase, before any is read.
TEST(DicomPhases, VoxelLimitCountsEveryPhase) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteTimeSeries(dir.path(), 4);
  LoadPolicy policy;
  policy.max_voxels = std::uint64_t(640) * 640 * 4 * 2;  // two phases fit, not three
  const std::string error = SeriesError(dir.path(), policy);
  EXPECT_NE(error.find("640x640x4 voxels x 3 phases = 4915200 voxels exceeds this server's limit of 3276800 voxels"),
            std::string::npos)
      << error;
}

// A phase missing at one position: the counts differ, and the message says so.
TEST(DicomPhases, PositionsOfUnequalCountsAreRefused) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto files = WriteTimeSeries(dir.path(), 4);
  fs::remove(files[1][2]);
  const std::string error = SeriesError(dir.path());
  EXPECT_NE(error.find("positions hold 3 and 2 slices: not one phase a position"), std::string::npos) << error;
  EXPECT_NE(error.find(dir.path().string()), std::string::npos) << "names the folder: " << error;
}

// Two files of one position at one trigger time are duplicates.
TEST(DicomPhases, SameTriggerTimeTwiceAtAPositionIsRefused) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto files = WriteTimeSeries(dir.path(), 4);
  EditHeader(files[2][1], [](gdcm::DataSet& ds) { SetTriggerTime(ds, kTrigger[0] * 1.1); });  // p = 0's at i = 1
  const std::string error = SeriesError(dir.path());
  EXPECT_NE(error.find("lie at the same position"), std::string::npos) << error;
  EXPECT_NE(error.find("duplicate slices"), std::string::npos) << error;
  EXPECT_NE(error.find("both with Trigger Time 330 ms"), std::string::npos) << error;
  EXPECT_NE(error.find(files[0][1].filename().string()), std::string::npos) << "names the files: " << error;
  EXPECT_NE(error.find(files[2][1].filename().string()), std::string::npos) << "names the files: " << error;
}

// More phases than cinevol holds: refused from the headers.
TEST(DicomPhases, MorePhasesThanTheLimitAreRefused) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  // One MR file made 2 x 2 pixels, written 4097 times at one position.
  const auto reader = ReadDicom(MrSlicesInOrder().front());
  gdcm::DataSet& ds = reader->GetFile().GetDataSet();
  gdcm::Attribute<0x0028, 0x0010> rows;
  rows.SetValue(2);
  ds.Replace(rows.GetAsDataElement());
  gdcm::Attribute<0x0028, 0x0011> columns;
  columns.SetValue(2);
  ds.Replace(columns.GetAsDataElement());
  gdcm::DataElement pixels(gdcm::Tag(0x7fe0, 0x0010));
  pixels.SetVR(gdcm::VR::OW);
  const char zeros[8] = {};
  pixels.SetByteValue(zeros, 8);
  ds.Replace(pixels);
  for (int k = 0; k <= kMaxPhases; ++k) {
    SetTriggerTime(ds, k);
    WriteDicom(*reader, dir / (std::to_string(k) + ".dcm"));
  }
  const std::string error = SeriesError(dir.path());
  EXPECT_NE(error.find("a time series of 4097 phases"), std::string::npos) << error;
  EXPECT_NE(error.find("cinevol reads 1 to 4096"), std::string::npos) << error;
}

// ------------------------------------------------ an enhanced multi-frame MR

// A sequence of `items` under `tag`, as scanners write them (undefined lengths).
gdcm::DataElement Sequence(const gdcm::Tag& tag, const std::vector<gdcm::DataSet>& items) {
  gdcm::SmartPointer<gdcm::SequenceOfItems> sq = new gdcm::SequenceOfItems;
  sq->SetLengthToUndefined();
  for (const gdcm::DataSet& nested : items) {
    gdcm::Item item;
    item.SetVLToUndefined();
    item.SetNestedDataSet(nested);
    sq->AddItem(item);
  }
  gdcm::DataElement de(tag);
  de.SetVR(gdcm::VR::SQ);
  de.SetValue(*sq);
  de.SetVLToUndefined();
  return de;
}

gdcm::DataSet Holding(std::initializer_list<gdcm::DataElement> elements) {
  gdcm::DataSet ds;
  for (const gdcm::DataElement& e : elements) ds.Replace(e);
  return ds;
}

// Frame Content with a Temporal Position Index (where given) and the stack
// position; Cardiac Synchronization with a Nominal Cardiac Trigger Delay.
gdcm::DataElement FrameContent(std::optional<unsigned> temporal_index, unsigned in_stack) {
  gdcm::DataSet content;
  gdcm::Attribute<0x0020, 0x9057> stack_position;
  stack_position.SetValue(in_stack);
  content.Replace(stack_position.GetAsDataElement());
  if (temporal_index) {
    gdcm::Attribute<0x0020, 0x9128> index;
    index.SetValue(*temporal_index);
    content.Replace(index.GetAsDataElement());
  }
  return Sequence(gdcm::Tag(0x0020, 0x9111), {content});
}

gdcm::DataElement CardiacTrigger(double ms) {
  gdcm::Attribute<0x0020, 0x9153> delay;
  delay.SetValue(ms);
  return Sequence(gdcm::Tag(0x0018, 0x9118), {Holding({delay.GetAsDataElement()})});
}

gdcm::DataElement Rescale(double slope, double intercept) {
  gdcm::Attribute<0x0028, 0x1053> s;
  s.SetValue(slope);
  gdcm::Attribute<0x0028, 0x1052> i;
  i.SetValue(intercept);
  gdcm::Attribute<0x0028, 0x1054> type;
  type.SetValue("US");
  return Sequence(gdcm::Tag(0x0028, 0x9145), {Holding({s.GetAsDataElement(), i.GetAsDataElement(),
                                                       type.GetAsDataElement()})});
}

// One frame of an enhanced MR: the MR slice whose pixels it holds, the MR
// slice whose position it takes, and its other per-frame groups.
struct EnhancedFrame {
  int pixels_of;
  int position_of;
  gdcm::DataSet groups;
};

// An Enhanced MR Image file of `frames` made from the MR's slices: the first
// slice's header with its plane, pixel measures and rescale moved into the
// Shared Functional Groups, each frame's position into its Per-frame ones.
void WriteEnhancedMr(const fs::path& file, const std::vector<EnhancedFrame>& frames) {
  const std::vector<fs::path> mr = MrSlicesInOrder();
  const auto base = ReadDicom(mr[0]);
  gdcm::DataSet& ds = base->GetFile().GetDataSet();
  const gdcm::Tag ipp(0x0020, 0x0032), iop(0x0020, 0x0037), spacing(0x0028, 0x0030), thickness(0x0018, 0x0050);
  const gdcm::DataSet shared =
      Holding({Sequence(gdcm::Tag(0x0020, 0x9116), {Holding({ds.GetDataElement(iop)})}),
               Sequence(gdcm::Tag(0x0028, 0x9110),
                        {Holding({ds.GetDataElement(spacing), ds.GetDataElement(thickness)})}),
               Rescale(1, 0)});
  ds.Replace(Sequence(gdcm::Tag(0x5200, 0x9229), {shared}));
  std::vector<gdcm::DataSet> per_frame;
  std::string pixels;
  for (const EnhancedFrame& f : frames) {
    gdcm::DataSet item = f.groups;
    const auto at = ReadDicom(mr[std::size_t(f.position_of)]);
    item.Replace(Sequence(gdcm::Tag(0x0020, 0x9113), {Holding({at->GetFile().GetDataSet().GetDataElement(ipp)})}));
    per_frame.push_back(item);
    const auto of = ReadDicom(mr[std::size_t(f.pixels_of)]);
    const gdcm::ByteValue* bytes = of->GetFile().GetDataSet().GetDataElement(gdcm::Tag(0x7fe0, 0x0010)).GetByteValue();
    pixels.append(bytes->GetPointer(), bytes->GetLength());
  }
  ds.Replace(Sequence(gdcm::Tag(0x5200, 0x9230), per_frame));
  for (const gdcm::Tag& moved : {ipp, iop, spacing, thickness, gdcm::Tag(0x0028, 0x1052), gdcm::Tag(0x0028, 0x1053)}) {
    ds.Remove(moved);
  }
  gdcm::Attribute<0x0028, 0x0008> number_of_frames;
  number_of_frames.SetValue(int(frames.size()));
  ds.Replace(number_of_frames.GetAsDataElement());
  gdcm::Attribute<0x0008, 0x0016> sop_class;
  sop_class.SetValue("1.2.840.10008.5.1.4.1.1.4.1");  // Enhanced MR Image Storage
  ds.Replace(sop_class.GetAsDataElement());
  base->GetFile().GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  gdcm::DataElement pixel_data(gdcm::Tag(0x7fe0, 0x0010));
  pixel_data.SetVR(gdcm::VR::OW);
  pixel_data.SetByteValue(pixels.data(), std::uint32_t(pixels.size()));
  ds.Replace(pixel_data);
  WriteDicom(*base, file);
}

// A cine of kCinePhases phases x 2 positions as one enhanced MR, as in
// WriteCine: frame (p, i) holds MR slice i + 2 p at MR slice i's position,
// Temporal Position Index p + 1 and Nominal Cardiac Trigger Delay 40 p + 3 i
// ms; the frames stored in a shuffled order. `edit` changes each frame's
// groups last.
template <class Edit>
void WriteEnhancedCine(const fs::path& file, Edit edit) {
  std::vector<EnhancedFrame> frames;
  for (int p = 0; p < kCinePhases; ++p) {
    for (int i = 0; i < 2; ++i) {
      EnhancedFrame& f = frames.emplace_back(EnhancedFrame{i + 2 * p, i, {}});
      f.groups.Replace(FrameContent(unsigned(p + 1), unsigned(i + 1)));
      f.groups.Replace(CardiacTrigger(40 * p + 3 * i));
      edit(f.groups, p, i);
    }
  }
  std::shuffle(frames.begin(), frames.end(), std::mt19937(59));
  WriteEnhancedMr(file, frames);
}

void WriteEnhancedCine(const fs::path& file) {
  WriteEnhancedCine(file, [](gdcm::DataSet&, int, int) {});
}

// One file of 20 frames is 10 phases of 640 x 640 x 2 by their Temporal
// Position Index, with times from their trigger delays, placed as the MR.
TEST(DicomPhases, AnEnhancedMultiFrameFileIsReadAsPhasesByTemporalPositionIndex) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteEnhancedCine(dir / "cine.dcm");
  const VolumeSeries cine = LoadSeries(dir.path());
  const Volume mr = LoadDicomSeries(MrFolder());
  ASSERT_NO_FATAL_FAILURE(ExpectTheCine(cine, mr));
  for (const Volume& phase : cine.phases) {
    EXPECT_EQ(phase.metadata().original_type, "uint16") << "stored values, the rescale the identity";
    EXPECT_EQ(phase.metadata().origin_mm, mr.metadata().origin_mm);
    EXPECT_EQ(phase.metadata().direction, mr.metadata().direction);
    EXPECT_FLOAT_EQ(phase.spacing_mm().x, mr.spacing_mm().x);
    EXPECT_FLOAT_EQ(phase.spacing_mm().y, mr.spacing_mm().y);
    EXPECT_FLOAT_EQ(phase.spacing_mm().z, mr.spacing_mm().z);
  }
}

// Without a Temporal Position Index the trigger delay orders the frames:
// here it runs against the phases' indices, which are left out.
TEST(DicomPhases, EnhancedFramesWithoutATemporalIndexFollowTheirTriggerDelay) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteEnhancedCine(dir / "cine.dcm", [](gdcm::DataSet& groups, int p, int i) {
    groups.Replace(FrameContent(std::nullopt, unsigned(i + 1)));
    groups.Replace(CardiacTrigger(40 * (kCinePhases - 1 - p) + 3 * i));  // phase p shown at kCinePhases - 1 - p
  });
  const VolumeSeries cine = LoadSeries(dir.path());
  ASSERT_EQ(cine.phases.size(), std::size_t(kCinePhases));
  const Volume mr = LoadDicomSeries(MrFolder());
  for (int k = 0; k < kCinePhases; ++k) ExpectPhaseHolds(cine, std::size_t(k), kCinePhases - 1 - k, mr);
  EXPECT_NEAR(cine.seconds.back(), 0.040 * (kCinePhases - 1), 1e-9);
}

// Each frame's own Pixel Value Transformation: phase 3's frames are scaled,
// every frame rescaled by its own.
TEST(DicomPhases, EachEnhancedFrameIsRescaledByItsOwnTransformation) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WriteEnhancedCine(dir / "cine.dcm", [](gdcm::DataSet& groups, int p, int) {
    if (p == 3) groups.Replace(Rescale(2, -5));
  });
  const VolumeSeries cine = LoadSeries(dir.path());
  ASSERT_EQ(cine.phases.size(), std::size_t(kCinePhases));
  const Volume mr = LoadDicomSeries(MrFolder());
  EXPECT_EQ(cine.phases[3].metadata().original_type, "uint16 (each frame rescaled by its own slope and intercept)");
  int differing = 0;
  for (int z = 0; z < 2; ++z) {
    for (int y = 0; y < 640; y += 31) {
      for (int x = 0; x < 640; x += 29) {
        differing += cine.phases[3].Value(x, y, z) != 2 * mr.Value(x, y, z + 6) - 5;
        differing += cine.phases[4].Value(x, y, z) != mr.Value(x, y, z + 8);
      }
    }
  }
  EXPECT_EQ(differing, 0);
}

// Refused by name: a frame in another orientation, a sequence not one item a
// frame, two frames of one place and time; the voxel limit counts every frame.
TEST(DicomPhases, BadEnhancedFramesAreRefusedByName) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  const auto error_of = [&](const std::string& name, auto edit, const LoadPolicy& policy = {}) {
    const fs::path folder = dir / name;
    fs::create_directory(folder);
    WriteEnhancedCine(folder / "cine.dcm", edit);
    return SeriesError(folder, policy);
  };
  std::string error = error_of("tilted", [](gdcm::DataSet& groups, int p, int i) {
    gdcm::Attribute<0x0020, 0x0037> iop;
    iop.SetValues(std::array<double, 6>{1, 0, 0, 0, 0.8, 0.6}.data(), 6);
    if (p == 4 && i == 1) groups.Replace(Sequence(gdcm::Tag(0x0020, 0x9116), {Holding({iop.GetAsDataElement()})}));
  });
  EXPECT_NE(error.find("orientation differs from frame 1's"), std::string::npos) << error;
  EXPECT_NE(error.find("cine.dcm"), std::string::npos) << error;

  error = error_of("twice", [](gdcm::DataSet& groups, int p, int i) {
    if (p == 7) groups.Replace(FrameContent(6, unsigned(i + 1)));  // phase 6's index again
  });
  EXPECT_NE(error.find("both with Temporal Position Index 6"), std::string::npos) << error;
  EXPECT_NE(error.find("frame "), std::string::npos) << "names the frames: " << error;

  LoadPolicy policy;
  policy.max_voxels = std::uint64_t(640) * 640 * 2 * 9;  // nine phases fit, not ten
  error = error_of("limit", [](gdcm::DataSet&, int, int) {}, policy);
  EXPECT_NE(error.find("640x640x2 voxels x 10 phases"), std::string::npos) << error;

  const fs::path short_file = dir / "short";
  fs::create_directory(short_file);
  WriteEnhancedCine(short_file / "cine.dcm");
  EditHeader(short_file / "cine.dcm", [](gdcm::DataSet& ds) {
    gdcm::Attribute<0x0028, 0x0008> frames;
    frames.SetValue(21);
    ds.Replace(frames.GetAsDataElement());
  });
  error = SeriesError(short_file);
  EXPECT_NE(error.find("Number of Frames is 21 and its Per-frame Functional Groups Sequence holds 20 items"),
            std::string::npos)
      << error;
}

}  // namespace
}  // namespace cinevol

// The DICOMweb client against a real PACS: Debian's Orthanc with its DICOMweb
// plugin, started for this suite on a loopback port (orthanc_process.h) and
// seeded through its REST API with a CT series (20 JPEG 2000 slices) and an MR
// series (4 slices) stamped from the shared data.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "core/error.h"
#include "pacs/dicomweb_client.h"
#include "pacs/orthanc_process.h"
#include "pacs/pacs_error.h"
#include "pacs/stamped_series.h"
#include "support/error_of.h"
#include "support/test_paths.h"

namespace cinevol::pacs {
namespace {

namespace fs = std::filesystem;
using cinevol::testing::ErrorOf;
using cinevol::testing::OrthancProcess;
using cinevol::testing::ReadWholeFile;
using cinevol::testing::ScratchDir;
using cinevol::testing::SeriesStamp;
using cinevol::testing::StampedSeries;

const SeriesStamp kCt{"2.25.3400001", "2.25.3400001.1", "CINEVOL-CT-1", "Cinevol^Ct"};  // 2022-12-08
const SeriesStamp kMr{"2.25.3400002", "2.25.3400002.1", "CINEVOL-MR-1", "Cinevol^Mr"};  // 2009-12-03
const SeriesStamp kStow{"2.25.3400003", "2.25.3400003.1", "CINEVOL-STOW-1", "Cinevol^Stow"};
constexpr std::size_t kMrSlices = 4;

struct Retrieved {
  std::vector<InstanceSummary> listed;
  std::map<std::string, std::string> bytes;  // by SOP Instance UID
  std::vector<std::size_t> progress;
  RetrieveStats stats;
};

class PacsOrthanc : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    skip_ = OrthancProcess::WhatIsMissing();
    if (skip_.empty() && !fs::is_directory(cinevol::testing::SharedData())) {
      skip_ = "the shared data are not at " + cinevol::testing::SharedData().string() + " (../shared/data)";
    }
    if (!skip_.empty()) return;
    folder_ = fs::temp_directory_path() / ("cinevol-PacsOrthanc-" + std::to_string(getpid()));
    fs::remove_all(folder_);
    fs::create_directories(folder_);
    try {
      StartAndSeed();
    } catch (const std::exception& e) {
      failure_ = std::string("seeding Orthanc failed: ") + e.what();
    }
  }

  static void StartAndSeed() {
    orthanc_ = std::make_unique<OrthancProcess>(folder_);
    if (!orthanc_->running()) {
      failure_ = "Orthanc did not start; its log:\n" + orthanc_->Log();
      return;
    }
    const fs::path shared = cinevol::testing::SharedData();
    const auto ct_files = cinevol::testing::DicomFilesIn(shared / "ct-body-totalsegmentator/example_ct_dicom");
    auto mr_files = cinevol::testing::DicomFilesIn(shared / "mr-chest-dicom-seg3d");
    mr_files.resize(std::min(mr_files.size(), kMrSlices));
    ct_ = cinevol::testing::StampSeries(ct_files, kCt, folder_ / "ct");
    mr_ = cinevol::testing::StampSeries(mr_files, kMr, folder_ / "mr");
    for (const StampedSeries* series : {&ct_, &mr_}) {
      for (const auto& instance : series->instances) {
        const long status = orthanc_->Upload(instance.bytes);
        if (status != 200) throw std::runtime_error("Orthanc answered an upload with HTTP " + std::to_string(status));
      }
    }
  }

  static void TearDownTestSuite() {
    orthanc_.reset();  // stops it by its pid
    if (!folder_.empty()) fs::remove_all(folder_);
  }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_ << "; skipping";
    ASSERT_TRUE(failure_.empty()) << failure_;
  }

  static PacsConfig Config() {
    PacsConfig config = orthanc_->Pacs();
    config.parallel_fetches = 3;
    return config;
  }

  static std::vector<std::string> StudyUids(const std::vector<StudySummary>& studies) {
    std::vector<std::string> uids;
    for (const StudySummary& study : studies) uids.push_back(study.study_uid);
    return uids;
  }

  static std::vector<std::string> Search(StudyQuery query) {
    return StudyUids(DicomWebClient(Config()).SearchStudies(query));
  }

  static Retrieved Retrieve(const PacsConfig& config, const SeriesStamp& stamp,
                            const std::atomic<bool>* cancel = nullptr) {
    Retrieved retrieved;
    RetrieveCallbacks callbacks;
    callbacks.on_listing = [&](const std::vector<InstanceSummary>& listed) { retrieved.listed = listed; };
    callbacks.on_instance = [&](const InstanceSummary& instance, const std::filesystem::path& file, std::uint64_t) {
      retrieved.bytes[instance.sop_instance_uid] = ReadWholeFile(file);
    };
    callbacks.on_progress = [&](std::size_t done, std::size_t) { retrieved.progress.push_back(done); };
    const ScratchDir folder;
    retrieved.stats =
        DicomWebClient(config).RetrieveSeries(stamp.study_uid, stamp.series_uid, folder.path(), callbacks, cancel);
    return retrieved;
  }

  static inline std::string skip_;
  static inline std::string failure_;
  static inline fs::path folder_;
  static inline std::unique_ptr<OrthancProcess> orthanc_;
  static inline StampedSeries ct_;
  static inline StampedSeries mr_;
};

bool Contains(const std::vector<std::string>& values, const std::string& value) {
  return std::find(values.begin(), values.end(), value) != values.end();
}

TEST_F(PacsOrthanc, ListensOnLoopbackOnly) {
  const std::string port = fmt::format(":{:04X} ", orthanc_->port());
  // /proc/net/tcp{,6}: "sl local_address rem_address st ...", addresses in hex, state 0A listening.
  const auto listeners = [&](const char* table) {
    std::vector<std::string> addresses;
    std::ifstream in(table);
    for (std::string line; std::getline(in, line);) {
      std::istringstream fields(line);
      std::string slot, local, remote, state;
      fields >> slot >> local >> remote >> state;
      if (state == "0A" && (local + " ").find(port) != std::string::npos) addresses.push_back(local);
    }
    return addresses;
  };
  EXPECT_EQ(listeners("/proc/net/tcp"), std::vector<std::string>{"0100007F" + port.substr(0, 5)});
  for (const std::string& address : listeners("/proc/net/tcp6")) {
    EXPECT_EQ(address, "00000000000000000000000001000000" + port.substr(0, 5)) << "listening beyond ::1";
  }
}

TEST_F(PacsOrthanc, SearchByPatientIdFindsThatPatientsStudyAndNoOther) {
  StudyQuery query;
  query.patient_id = kCt.patient_id;
  const auto studies = DicomWebClient(Config()).SearchStudies(query);
  ASSERT_EQ(studies.size(), 1u);
  const StudySummary& study = studies.front();
  EXPECT_EQ(study.study_uid, kCt.study_uid);
  EXPECT_EQ(study.patient_id, kCt.patient_id);
  EXPECT_EQ(study.patient_name, kCt.patient_name);
  EXPECT_EQ(study.study_date, "20221208");
  EXPECT_TRUE(Contains(study.modalities, "CT"));
  EXPECT_EQ(study.series_count, 1);
  EXPECT_EQ(study.instance_count, 20);
  query.patient_id = "NOBODY-HERE";
  EXPECT_TRUE(Search(query).empty());
}

TEST_F(PacsOrthanc, SearchByModalityFindsTheStudyAndNotOthers) {
  StudyQuery query;
  query.modality = "CT";
  auto uids = Search(query);
  EXPECT_TRUE(Contains(uids, kCt.study_uid));
  EXPECT_FALSE(Contains(uids, kMr.study_uid));
  query.modality = "MR";
  uids = Search(query);
  EXPECT_TRUE(Contains(uids, kMr.study_uid));
  EXPECT_FALSE(Contains(uids, kCt.study_uid));
}

TEST_F(PacsOrthanc, SearchByDateRangeFindsTheStudiesInsideIt) {
  StudyQuery query;
  query.study_date_from = "20220101";
  query.study_date_to = "20221231";
  auto uids = Search(query);
  EXPECT_TRUE(Contains(uids, kCt.study_uid));
  EXPECT_FALSE(Contains(uids, kMr.study_uid));
  query.study_date_from = "";
  query.study_date_to = "20100101";  // open at the start
  uids = Search(query);
  EXPECT_TRUE(Contains(uids, kMr.study_uid));
  EXPECT_FALSE(Contains(uids, kCt.study_uid));
}

TEST_F(PacsOrthanc, SearchByPatientNameAndAccessionNumber) {
  StudyQuery query;
  query.patient_name = "Cinevol^M*";
  EXPECT_EQ(Search(query), std::vector<std::string>{kMr.study_uid});
  query = {};
  query.accession_number = "4346556";  // the MR's, kept from the shared file
  EXPECT_EQ(Search(query), std::vector<std::string>{kMr.study_uid});
}

TEST_F(PacsOrthanc, SearchPagesWithLimitAndOffset) {
  StudyQuery query;
  query.limit = 100;
  const auto all = Search(query);
  ASSERT_GE(all.size(), 2u);
  ASSERT_LE(all.size(), 10u);
  std::set<std::string> paged;
  for (std::size_t offset = 0; offset < all.size(); ++offset) {
    query.limit = 1;
    query.offset = int(offset);
    const auto page = Search(query);
    ASSERT_EQ(page.size(), 1u) << "offset " << offset;
    paged.insert(page.front());
  }
  EXPECT_EQ(paged, std::set<std::string>(all.begin(), all.end()));
}

TEST_F(PacsOrthanc, SearchSeriesGivesModalityDescriptionAndInstanceCounts) {
  const DicomWebClient client(Config());
  const auto ct = client.SearchSeries(kCt.study_uid);
  ASSERT_EQ(ct.size(), 1u);
  EXPECT_EQ(ct[0].series_uid, kCt.series_uid);
  EXPECT_EQ(ct[0].modality, "CT");
  EXPECT_EQ(ct[0].description, "CT Body 3.0");
  EXPECT_EQ(ct[0].instance_count, 20);
  const auto mr = client.SearchSeries(kMr.study_uid);
  ASSERT_EQ(mr.size(), 1u);
  EXPECT_EQ(mr[0].modality, "MR");
  EXPECT_EQ(mr[0].instance_count, std::int64_t(kMrSlices));
}

TEST_F(PacsOrthanc, RetrieveSeriesReturnsEveryInstanceByteForByte) {
  const auto start = std::chrono::steady_clock::now();
  const Retrieved retrieved = Retrieve(Config(), kCt);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(retrieved.listed.size(), ct_.instances.size());
  EXPECT_EQ(retrieved.listed.front().rows, 512);
  EXPECT_EQ(retrieved.listed.front().columns, 512);
  ASSERT_EQ(retrieved.bytes.size(), ct_.instances.size());
  for (const auto& uploaded : ct_.instances) {
    const auto found = retrieved.bytes.find(uploaded.sop_instance_uid);
    ASSERT_NE(found, retrieved.bytes.end()) << uploaded.sop_instance_uid;
    EXPECT_TRUE(found->second == uploaded.bytes) << uploaded.sop_instance_uid << " differs from what was uploaded";
  }
  EXPECT_EQ(retrieved.progress.size(), ct_.instances.size());
  EXPECT_EQ(retrieved.progress.back(), ct_.instances.size());
  EXPECT_EQ(retrieved.stats.instances, ct_.instances.size());
  EXPECT_GE(retrieved.stats.most_fetches_at_once, 1);
  EXPECT_LE(retrieved.stats.most_fetches_at_once, 3);
  std::cout << "retrieved 20 JPEG 2000 CT instances (" << retrieved.stats.bytes << " bytes) in " << seconds
            << " s, at most " << retrieved.stats.most_fetches_at_once << " at once\n";
}

TEST_F(PacsOrthanc, MaxInstancesRefusesTheSeriesBeforeAnyFetch) {
  PacsConfig config = Config();
  config.max_instances = 5;
  bool fetched = false;
  RetrieveCallbacks callbacks;
  callbacks.on_listing = [&](const auto&) { fetched = true; };
  callbacks.on_instance = [&](const auto&, const auto&, auto) { fetched = true; };
  const ScratchDir folder;
  try {
    DicomWebClient(config).RetrieveSeries(kCt.study_uid, kCt.series_uid, folder.path(), callbacks);
    ADD_FAILURE() << "a series of 20 retrieved under max_instances 5";
  } catch (const OverLimit& e) {
    EXPECT_EQ(e.flag(), "pacs-max-instances");
    EXPECT_NE(std::string(e.what()).find("max_instances"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("orthanc-test"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fetched);
}

TEST_F(PacsOrthanc, SeriesByteCapStopsTheRetrievePartWay) {
  PacsConfig config = Config();
  config.max_series_bytes = 3 * ct_.instances.front().bytes.size();  // about 3 of the 20 instances
  std::atomic<int> delivered{0};
  RetrieveCallbacks callbacks;
  callbacks.on_instance = [&](const auto&, const auto&, auto) { ++delivered; };
  const ScratchDir folder;
  try {
    DicomWebClient(config).RetrieveSeries(kCt.study_uid, kCt.series_uid, folder.path(), callbacks);
    ADD_FAILURE() << "retrieved past max_series_bytes";
  } catch (const OverLimit& e) {
    EXPECT_EQ(e.flag(), "pacs-max-series-bytes");
    EXPECT_NE(std::string(e.what()).find("max_series_bytes"), std::string::npos) << e.what();
  }
  EXPECT_LE(delivered.load(), 3);
}

TEST_F(PacsOrthanc, ResponseCapRefusesAnInstanceLargerThanIt) {
  PacsConfig config = Config();
  config.max_response_bytes = 100 * 1024;  // each CT instance is about 155 KiB
  const std::string error = ErrorOf<OverLimit>([&] { Retrieve(config, kCt); });
  EXPECT_NE(error.find("max_response_bytes"), std::string::npos) << error;
  EXPECT_NE(error.find("102400"), std::string::npos) << error;
}

TEST_F(PacsOrthanc, CancelStopsTheRetrieveAndDeliversNothingAfter) {
  std::atomic<bool> cancel{false};
  std::size_t delivered = 0;
  std::chrono::steady_clock::time_point cancelled_at;
  RetrieveCallbacks callbacks;
  callbacks.on_instance = [&](const auto&, const auto&, auto) {
    ++delivered;
    cancelled_at = std::chrono::steady_clock::now();
    cancel = true;
  };
  const ScratchDir folder;
  EXPECT_THROW(DicomWebClient(Config()).RetrieveSeries(kCt.study_uid, kCt.series_uid, folder.path(), callbacks, &cancel),
               Cancelled);
  EXPECT_EQ(delivered, 1u);
  EXPECT_LT(std::chrono::steady_clock::now() - cancelled_at, std::chrono::seconds(2));
}

TEST_F(PacsOrthanc, WrongPasswordIsAnAuthErrorNamingThePacsNotThePassword) {
  PacsConfig config = Config();
  config.credentials.password = "not-the-" + orthanc_->password();
  try {
    DicomWebClient(config).SearchStudies({});
    ADD_FAILURE() << "a search with a wrong password succeeded";
  } catch (const PacsError& e) {
    const std::string message = e.what();
    EXPECT_TRUE(e.refused_credentials());
    EXPECT_NE(message.find("'orthanc-test'"), std::string::npos) << message;
    EXPECT_NE(message.find("credentials"), std::string::npos) << message;
    EXPECT_NE(message.find("401"), std::string::npos) << message;
    EXPECT_EQ(message.find(orthanc_->password()), std::string::npos) << message;
  }
}

TEST_F(PacsOrthanc, UnknownSeriesIsAClearError) {
  try {
    Retrieve(Config(), {kCt.study_uid, "2.25.999", "", ""});
    ADD_FAILURE() << "an unknown series retrieved";
  } catch (const PacsError& e) {
    EXPECT_EQ(e.http_status(), 404);
    EXPECT_NE(std::string(e.what()).find("orthanc-test"), std::string::npos) << e.what();
  }
}

TEST_F(PacsOrthanc, StoredInstanceIsFoundBySearchAndRetrievedIntact) {
  const fs::path mr_source = cinevol::testing::DicomFilesIn(cinevol::testing::SharedData() / "mr-chest-dicom-seg3d")[0];
  const StampedSeries stow = cinevol::testing::StampSeries({mr_source}, kStow, folder_ / "stow");
  const DicomWebClient client(Config());
  const StoreResult stored = client.StoreInstances(kStow.study_uid, {stow.instances[0].bytes});
  EXPECT_EQ(stored.stored_sop_instance_uids, std::vector<std::string>{stow.instances[0].sop_instance_uid});
  StudyQuery query;
  query.patient_id = kStow.patient_id;
  EXPECT_EQ(StudyUids(client.SearchStudies(query)), std::vector<std::string>{kStow.study_uid});
  const auto series = client.SearchSeries(kStow.study_uid);
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(series[0].instance_count, 1);
  const Retrieved retrieved = Retrieve(Config(), kStow);
  ASSERT_EQ(retrieved.bytes.size(), 1u);
  EXPECT_TRUE(retrieved.bytes.begin()->second == stow.instances[0].bytes);
}

TEST_F(PacsOrthanc, StoreIntoAnotherStudyReportsTheRefusal) {
  // The instance says it belongs to the MR study; posted to the CT study, the PACS refuses it.
  const std::string error =
      ErrorOf<PacsError>([&] { DicomWebClient(Config()).StoreInstances(kCt.study_uid, {mr_.instances[0].bytes}); });
  EXPECT_NE(error.find("stored 0 of 1"), std::string::npos) << error;
  EXPECT_NE(error.find(mr_.instances[0].sop_instance_uid), std::string::npos) << error;
  EXPECT_NE(error.find("0x0110"), std::string::npos) << error;  // Orthanc's reason: processing failure
}

}  // namespace
}  // namespace cinevol::pacs

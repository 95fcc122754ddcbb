// Renders as DICOM Secondary Captures (pacs/secondary_capture.h): read back by GDCM and by DCMTK's tools, hostile
// inputs refused by name, files that are not cinevol renders refused, and one stored into a real Orthanc.
#include "pacs/secondary_capture.h"

#include <gdcmImageReader.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>

#include "core/error.h"
#include "pacs/dicom_json.h"
#include "pacs/dicomweb_client.h"
#include "pacs/orthanc_process.h"
#include "pacs/stamped_series.h"
#include "support/error_of.h"
#include "support/shell_command.h"
#include "support/test_paths.h"

namespace cinevol::pacs {
namespace {

namespace fs = std::filesystem;
using cinevol::testing::ErrorOf;

const char* kScene = R"({"camera": {"position": [0, -400.5, 120], "fovDeg": 30},
  "preset": "ct-bone", "transfer": {"points": [{"value": -1000, "opacity": 0}, {"value": 3000, "opacity": 0.8}]}})";

SourceStudy Source() {
  SourceStudy source;
  source.patient_name = "Cinevol^Capture";
  source.patient_id = "CINEVOL-SC-1";
  source.patient_birth_date = "19700101";
  source.patient_sex = "O";
  source.study_uid = "2.25.3400341";
  source.study_id = "SC1";
  source.study_date = "20240102";
  source.study_time = "093000";
  source.accession_number = "ACC-SC-1";
  source.referring_physician = "Ref^Erring";
  source.study_description = "Chest CT";
  source.series_uid = "2.25.3400341.1";
  return source;
}

// A picture whose every byte says where it is: 33 x 17 makes an odd pixel length, padded in the file.
SecondaryCaptureImage Picture(int width = 33, int height = 17) {
  SecondaryCaptureImage image{width, height, {}};
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.rgb.push_back(static_cast<std::uint8_t>(x * 7));
      image.rgb.push_back(static_cast<std::uint8_t>(y * 13));
      image.rgb.push_back(static_cast<std::uint8_t>((x + y) * 3 + 1));
    }
  }
  return image;
}

RenderRecipe Recipe(const std::string& preset = "ct-bone") { return {kScene, "2.25.3400341.1", "0.9.0", preset}; }

std::string TextAt(const gdcm::DataSet& data, std::uint16_t group, std::uint16_t element) {
  const gdcm::Tag tag(group, element);
  if (!data.FindDataElement(tag) || data.GetDataElement(tag).GetByteValue() == nullptr) return "(absent)";
  const gdcm::ByteValue* value = data.GetDataElement(tag).GetByteValue();
  std::string text(value->GetPointer(), value->GetLength());
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  return text;
}

google::protobuf::Value Json(const std::string& text) {
  google::protobuf::Value value;
  EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(text, &value).ok()) << text;
  return value;
}

using cinevol::testing::CommandResult;
using cinevol::testing::Installed;
using cinevol::testing::RunCommand;
using cinevol::testing::WriteFile;

TEST(SecondaryCapture, GdcmReadsBackTheSamePixelsAsAnRgbSecondaryCapture) {
  const SecondaryCaptureImage picture = Picture();
  const std::string file = MakeSecondaryCapture(Source(), picture, Recipe());
  std::istringstream in(file);
  gdcm::ImageReader reader;
  reader.SetStream(in);
  ASSERT_TRUE(reader.Read());
  const gdcm::Image& image = reader.GetImage();
  EXPECT_EQ(image.GetDimension(0), 33u);
  EXPECT_EQ(image.GetDimension(1), 17u);
  EXPECT_EQ(image.GetPhotometricInterpretation(), gdcm::PhotometricInterpretation::RGB);
  EXPECT_EQ(image.GetPixelFormat(), gdcm::PixelFormat(3, 8, 8, 7, 0));
  EXPECT_EQ(reader.GetFile().GetHeader().GetDataSetTransferSyntax(), gdcm::TransferSyntax::ExplicitVRLittleEndian);
  ASSERT_EQ(image.GetBufferLength(), picture.rgb.size());
  std::vector<std::uint8_t> pixels(image.GetBufferLength());
  ASSERT_TRUE(image.GetBuffer(reinterpret_cast<char*>(pixels.data())));
  EXPECT_TRUE(pixels == picture.rgb) << "pixels differ";
  const gdcm::DataSet& data = reader.GetFile().GetDataSet();
  EXPECT_EQ(TextAt(data, 0x0008, 0x0016), kSecondaryCaptureSopClass);
  EXPECT_EQ(TextAt(reader.GetFile().GetHeader(), 0x0002, 0x0002), kSecondaryCaptureSopClass);
  EXPECT_EQ(TextAt(data, 0x0008, 0x0060), "OT");
  EXPECT_EQ(TextAt(data, 0x0008, 0x0064), "WSD");
  EXPECT_EQ(TextAt(data, 0x0028, 0x0301), "NO");
  EXPECT_EQ(TextAt(data, 0x0008, 0x103e), "cinevol render: ct-bone");
  EXPECT_EQ(TextAt(data, 0x0020, 0x0011), std::to_string(kRenderSeriesNumber));
  EXPECT_EQ(TextAt(data, 0x0020, 0x0013), "1");
  EXPECT_EQ(TextAt(data, 0x0008, 0x0023).size(), 8u) << "content date";
  EXPECT_EQ(TextAt(data, 0x0008, 0x0005), "(absent)") << "ASCII needs no character set";
}

TEST(SecondaryCapture, CopiesThePatientAndStudyAttributesOfTheSource) {
  const std::string file = MakeSecondaryCapture(Source(), Picture(), Recipe());
  std::istringstream in(file);
  gdcm::Reader reader;
  reader.SetStream(in);
  ASSERT_TRUE(reader.Read());
  const gdcm::DataSet& data = reader.GetFile().GetDataSet();
  const SourceStudy source = Source();
  EXPECT_EQ(TextAt(data, 0x0010, 0x0010), source.patient_name);
  EXPECT_EQ(TextAt(data, 0x0010, 0x0020), source.patient_id);
  EXPECT_EQ(TextAt(data, 0x0010, 0x0030), source.patient_birth_date);
  EXPECT_EQ(TextAt(data, 0x0010, 0x0040), source.patient_sex);
  EXPECT_EQ(TextAt(data, 0x0020, 0x000d), source.study_uid);
  EXPECT_EQ(TextAt(data, 0x0020, 0x0010), source.study_id);
  EXPECT_EQ(TextAt(data, 0x0008, 0x0020), source.study_date);
  EXPECT_EQ(TextAt(data, 0x0008, 0x0030), source.study_time);
  EXPECT_EQ(TextAt(data, 0x0008, 0x0050), source.accession_number);
  EXPECT_EQ(TextAt(data, 0x0008, 0x0090), source.referring_physician);
  EXPECT_EQ(TextAt(data, 0x0008, 0x1030), source.study_description);
  EXPECT_NE(TextAt(data, 0x0020, 0x000e), source.series_uid) << "a render is a new series";
}

TEST(SecondaryCapture, EachCaptureGetsNewValidSeriesAndInstanceUids) {
  SecondaryCaptureUids first, second;
  const std::string file = MakeSecondaryCapture(Source(), Picture(), Recipe(), &first);
  MakeSecondaryCapture(Source(), Picture(), Recipe(), &second);
  std::set<std::string> uids{Source().study_uid, Source().series_uid};
  for (const std::string& uid :
       {first.series_uid, first.sop_instance_uid, second.series_uid, second.sop_instance_uid}) {
    EXPECT_TRUE(IsValidUid(uid)) << uid;
    EXPECT_EQ(uid.rfind("2.25.", 0), 0u) << uid;
    EXPECT_TRUE(uids.insert(uid).second) << uid << " repeats";
  }
  EXPECT_EQ(first.study_uid, Source().study_uid);
  const ReadCapture read = ReadSecondaryCapture(file);
  EXPECT_EQ(read.uids.study_uid, first.study_uid);
  EXPECT_EQ(read.uids.series_uid, first.series_uid);
  EXPECT_EQ(read.uids.sop_instance_uid, first.sop_instance_uid);
}

TEST(SecondaryCapture, TheRecipeReadsBackByteForByte) {
  const std::string file = MakeSecondaryCapture(Source(), Picture(), Recipe());
  const ReadCapture read = ReadSecondaryCapture(file);
  EXPECT_EQ(read.recipe_json,
            std::string(R"({"scene":)") + kScene +
                R"(,"sourceSeriesUid":"2.25.3400341.1","cinevolVersion":"0.9.0","preset":"ct-bone"})");
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(Json(read.scene_json), Json(kScene)))
      << read.scene_json;
  EXPECT_EQ(read.source_series_uid, "2.25.3400341.1");
  EXPECT_EQ(read.cinevol_version, "0.9.0");
  EXPECT_EQ(read.preset, "ct-bone");
  EXPECT_EQ(read.patient_id, Source().patient_id);
  EXPECT_EQ(read.patient_name, Source().patient_name);
  EXPECT_EQ(read.width, 33);
  EXPECT_EQ(read.height, 17);
}

TEST(SecondaryCapture, NonAsciiTextIsUtf8AndQuotesInThePresetStayJson) {
  SourceStudy source = Source();
  source.patient_name = "Müller^Zoë";
  RenderRecipe recipe = Recipe("Knochen \"weich\" – ß");
  recipe.source_series_uid.clear();  // taken from the source
  const std::string file = MakeSecondaryCapture(source, Picture(), recipe);
  std::istringstream in(file);
  gdcm::Reader reader;
  reader.SetStream(in);
  ASSERT_TRUE(reader.Read());
  EXPECT_EQ(TextAt(reader.GetFile().GetDataSet(), 0x0008, 0x0005), "ISO_IR 192");
  EXPECT_EQ(TextAt(reader.GetFile().GetDataSet(), 0x0008, 0x103e), "cinevol render: Knochen \"weich\" – ß");
  const ReadCapture read = ReadSecondaryCapture(file);
  EXPECT_EQ(read.patient_name, "Müller^Zoë");
  EXPECT_EQ(read.preset, "Knochen \"weich\" – ß");
  EXPECT_EQ(read.source_series_uid, Source().series_uid);
}

TEST(SecondaryCapture, ALongPresetIsCutInTheDescriptionButKeptWholeInTheRecipe) {
  const std::string preset(60, 'p');
  const std::string file = MakeSecondaryCapture(Source(), Picture(), Recipe(preset));
  std::istringstream in(file);
  gdcm::Reader reader;
  reader.SetStream(in);
  ASSERT_TRUE(reader.Read());
  EXPECT_EQ(TextAt(reader.GetFile().GetDataSet(), 0x0008, 0x103e), "cinevol render: " + std::string(48, 'p'));
  EXPECT_EQ(ReadSecondaryCapture(file).preset, preset);
}

// DCMTK (dcmftest, dcmdump, dcm2pnm) and dicom3tools' dciodvfy are installed
// by scripts/install-deps.sh: a check that skipped where they are missing
// could never fail in CI, so their absence fails the test.
TEST(SecondaryCapture, DcmtkReadsTheFileAndItsPixels) {
  for (const char* tool : {"dcmftest", "dcmdump", "dcm2pnm"}) {
    ASSERT_TRUE(Installed(tool)) << tool << " (DCMTK) is not installed: run scripts/install-deps.sh";
  }
  cinevol::testing::ScratchDir scratch;
  const SecondaryCaptureImage picture = Picture();
  const fs::path dicom = scratch / "capture.dcm";
  WriteFile(dicom, MakeSecondaryCapture(Source(), picture, Recipe()));
  const std::string path = "'" + dicom.string() + "'";
  {
    const CommandResult result = RunCommand("dcmftest " + path);
    EXPECT_EQ(result.status, 0) << result.output;
    EXPECT_EQ(result.output.rfind("yes:", 0), 0u) << result.output;
  }
  {
    const CommandResult result = RunCommand("dcmdump " + path);
    EXPECT_EQ(result.status, 0) << result.output;
    EXPECT_EQ(result.output.find("E:"), std::string::npos) << result.output;
    EXPECT_EQ(result.output.find("W:"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("CINEVOL RECIPE"), std::string::npos) << result.output;
  }
  const fs::path ppm = scratch / "capture.ppm";
  const CommandResult result = RunCommand("dcm2pnm +op " + path + " '" + ppm.string() + "'");
  ASSERT_EQ(result.status, 0) << result.output;
  const std::string header = "P6\n33 17\n255\n";
  const std::string bytes = cinevol::testing::ReadWholeFile(ppm);
  ASSERT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_TRUE(bytes.substr(header.size()) == std::string(picture.rgb.begin(), picture.rgb.end()))
      << "DCMTK decodes other pixels";
}

// Every object cinevol writes passes David Clunie's validator with no error;
// its warnings are the ones docs/pacs.md lists and justifies.
TEST(SecondaryCapture, DciodvfyFindsNoErrorAndOnlyTheListedWarnings) {
  ASSERT_TRUE(Installed("dciodvfy")) << "dciodvfy (dicom3tools) is not installed: run scripts/install-deps.sh";
  cinevol::testing::ScratchDir scratch;
  const fs::path dicom = scratch / "capture.dcm";
  WriteFile(dicom, MakeSecondaryCapture(Source(), Picture(), Recipe()));
  const CommandResult result = RunCommand("dciodvfy '" + dicom.string() + "'");
  std::istringstream lines(result.output);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_EQ(line.find("Error"), std::string::npos) << result.output;
    if (line.find("Warning") == std::string::npos) continue;
    // The recipe's private block (a validator knows no private tag), and
    // Laterality sent empty because it is unknown to a render (docs/pacs.md).
    const bool listed = line.find("(0x0041,0x1001)  ?  - Warning - Unrecognized tag") != std::string::npos ||
                        line.find("is only permitted to be empty when actually unknown") != std::string::npos;
    EXPECT_TRUE(listed) << line;
  }
}

TEST(SecondaryCapture, HostileInputsAreRefusedNamingTheField) {
  const auto refusal = [](SourceStudy source, SecondaryCaptureImage image, RenderRecipe recipe) {
    return ErrorOf<InputError>([&] { MakeSecondaryCapture(source, image, recipe); });
  };
  const auto source_with = [](auto edit) {
    SourceStudy source = Source();
    edit(source);
    return source;
  };
  const auto recipe_with = [](auto edit) {
    RenderRecipe recipe = Recipe();
    edit(recipe);
    return recipe;
  };
  const SecondaryCaptureImage picture = Picture();
  struct Case {
    std::string message;
    std::string field;
  };
  const std::vector<Case> cases{
      {refusal(source_with([](SourceStudy& s) { s.study_uid = "1.2.abc"; }), picture, Recipe()), "source.study_uid"},
      {refusal(source_with([](SourceStudy& s) { s.study_uid = ""; }), picture, Recipe()), "source.study_uid"},
      {refusal(source_with([](SourceStudy& s) { s.study_uid = "1." + std::string(70, '2'); }), picture, Recipe()),
       "source.study_uid"},
      {refusal(source_with([](SourceStudy& s) { s.patient_id = std::string(200, 'X'); }), picture, Recipe()),
       "source.patient_id is 200 characters; LO allows at most 64"},
      {refusal(source_with([](SourceStudy& s) { s.patient_name = "Evil\nName"; }), picture, Recipe()),
       "source.patient_name holds a control character"},
      {refusal(source_with([](SourceStudy& s) { s.patient_name = std::string(65, 'N'); }), picture, Recipe()),
       "source.patient_name"},
      {refusal(source_with([](SourceStudy& s) { s.study_description = "a\\b"; }), picture, Recipe()),
       "source.study_description holds a backslash"},
      {refusal(source_with([](SourceStudy& s) { s.accession_number = std::string(17, '1'); }), picture, Recipe()),
       "source.accession_number is 17 characters; SH allows at most 16"},
      {refusal(source_with([](SourceStudy& s) { s.study_date = "2024-01-02"; }), picture, Recipe()),
       "source.study_date"},
      {refusal(source_with([](SourceStudy& s) { s.patient_id = "\xff\xfe"; }), picture, Recipe()),
       "source.patient_id is not valid UTF-8"},
      {refusal(Source(), {0, 17, {}}, Recipe()), "image.width is 0"},
      {refusal(Source(), {33, kMaxCaptureSide + 1, {}}, Recipe()), "image.height"},
      {refusal(Source(), {33, 17, std::vector<std::uint8_t>(33 * 17 * 3 - 1)}, Recipe()), "image.rgb holds 1682 bytes"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) { r.scene_json = "[1, 2]"; })), "recipe.scene_json"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) { r.scene_json = "{\"a\": "; })),
       "recipe.scene_json"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) {
                 r.scene_json = std::string(100000, '[') + std::string(100000, ']');
               })),
       "recipe.scene_json"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) { r.source_series_uid = "2.25.9"; })),
       "recipe.source_series_uid differs from source.series_uid"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) { r.cinevol_version = "1.0\"}"; })),
       "recipe.cinevol_version"},
      {refusal(Source(), picture, recipe_with([](RenderRecipe& r) { r.preset = std::string(65, 'p'); })),
       "recipe.preset"},
  };
  for (const Case& c : cases) EXPECT_NE(c.message.find(c.field), std::string::npos) << c.message;
}

TEST(SecondaryCapture, ReadRefusesWhatIsNotACinevolRender) {
  EXPECT_NE(ErrorOf<InputError>([] { ReadSecondaryCapture(""); }).find("not a cinevol render"), std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([] { ReadSecondaryCapture(std::string(4096, 'x')); }).find("not a cinevol render"),
            std::string::npos);
  const std::string capture = MakeSecondaryCapture(Source(), Picture(), Recipe());
  EXPECT_NE(ErrorOf<InputError>([&] { ReadSecondaryCapture(capture.substr(0, 700)); }).find("not a cinevol render"),
            std::string::npos);
  // A Secondary Capture of someone else's: the same file without the recipe block.
  std::istringstream in(capture);
  gdcm::Reader reader;
  reader.SetStream(in);
  ASSERT_TRUE(reader.Read());
  reader.GetFile().GetDataSet().Remove(gdcm::Tag(kRecipeGroup, 0x0010));
  reader.GetFile().GetDataSet().Remove(gdcm::Tag(kRecipeGroup, 0x1001));
  gdcm::Writer writer;
  writer.SetFile(reader.GetFile());
  std::ostringstream out;
  writer.SetStream(out);
  ASSERT_TRUE(writer.Write());
  EXPECT_NE(ErrorOf<InputError>([&] { ReadSecondaryCapture(out.str()); }).find("no private block \"CINEVOL RECIPE\""),
            std::string::npos);
}

// A file from a PACS is not trusted: every truncation and every corrupted byte before the pixels reads or is
// refused, and never takes the process down.
TEST(SecondaryCapture, ReadSurvivesEveryTruncationAndCorruptedByte) {
  const std::string capture = MakeSecondaryCapture(Source(), Picture(), Recipe());
  const std::size_t header = capture.size() - 33 * 17 * 3 - 1 - 12;  // the pixels, their padding and element header
  int refused = 0;
  const auto read = [&](const std::string& bytes) {
    try {
      ReadSecondaryCapture(bytes);
    } catch (const InputError&) {
      ++refused;
    }
  };
  for (std::size_t size = 0; size < header; ++size) read(capture.substr(0, size));
  EXPECT_EQ(refused, int(header)) << "a capture cut before its pixels read as whole";
  for (std::size_t at = 0; at < header; ++at) {
    for (const char value : {'\x00', '\xff', '\x80'}) {
      std::string corrupted = capture;
      corrupted[at] = value;
      read(corrupted);
    }
  }
}

TEST(SecondaryCapture, ReadRefusesAnMrSliceOfTheSharedData) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const fs::path folder = cinevol::testing::SharedData() / "mr-chest-dicom-seg3d";
  const auto files = cinevol::testing::DicomFilesIn(folder);
  ASSERT_FALSE(files.empty()) << folder;
  const std::string message = ErrorOf<InputError>([&] { ReadSecondaryCapture(cinevol::testing::ReadWholeFile(files[0])); });
  EXPECT_NE(message.find("not a cinevol render: SOP class 1.2.840.10008.5.1.4.1.1.4,"), std::string::npos) << message;
}

// End to end: the capture stored (STOW-RS) into the source's study of a real Orthanc, found there by a series
// search, retrieved and its recipe read.
TEST(SecondaryCaptureOrthanc, StoredInTheSourceStudyIsFoundBySearchWithItsRecipe) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const std::string missing = cinevol::testing::OrthancProcess::WhatIsMissing();
  if (!missing.empty()) GTEST_SKIP() << missing << "; skipping";
  cinevol::testing::ScratchDir scratch;
  const cinevol::testing::SeriesStamp stamp{"2.25.3400342", "2.25.3400342.1", "CINEVOL-SC-2", "Cinevol^Sc"};
  const auto mr = cinevol::testing::DicomFilesIn(cinevol::testing::SharedData() / "mr-chest-dicom-seg3d");
  const auto seeded = cinevol::testing::StampSeries({mr.at(0)}, stamp, scratch / "mr");
  cinevol::testing::OrthancProcess orthanc(scratch.path());
  ASSERT_TRUE(orthanc.running()) << orthanc.Log();
  ASSERT_EQ(orthanc.Upload(seeded.instances.at(0).bytes), 200);

  SourceStudy source = Source();
  source.study_uid = stamp.study_uid;
  source.series_uid = stamp.series_uid;
  source.patient_id = stamp.patient_id;
  source.patient_name = stamp.patient_name;
  RenderRecipe recipe = Recipe("mr-default");
  recipe.source_series_uid = stamp.series_uid;
  SecondaryCaptureUids uids;
  const std::string capture = MakeSecondaryCapture(source, Picture(), recipe, &uids);
  const DicomWebClient client(orthanc.Pacs());
  EXPECT_EQ(client.StoreInstances(stamp.study_uid, {capture}).stored_sop_instance_uids,
            std::vector<std::string>{uids.sop_instance_uid});

  const std::vector<SeriesSummary> series = client.SearchSeries(stamp.study_uid);
  ASSERT_EQ(series.size(), 2u) << "the source series and the render";
  const auto render = std::find_if(series.begin(), series.end(),
                                   [&](const SeriesSummary& s) { return s.series_uid == uids.series_uid; });
  ASSERT_NE(render, series.end());
  EXPECT_EQ(render->modality, "OT");
  EXPECT_EQ(render->description, "cinevol render: mr-default");
  EXPECT_EQ(render->series_number, kRenderSeriesNumber);
  EXPECT_EQ(render->instance_count, 1);

  std::string retrieved;
  RetrieveCallbacks callbacks;
  callbacks.on_instance = [&](const InstanceSummary&, const std::filesystem::path& file, std::uint64_t) {
    retrieved = cinevol::testing::ReadWholeFile(file);
  };
  const cinevol::testing::ScratchDir folder;
  client.RetrieveSeries(stamp.study_uid, uids.series_uid, folder.path(), callbacks);
  EXPECT_EQ(retrieved, capture) << "the PACS keeps the file as sent";
  const ReadCapture read = ReadSecondaryCapture(retrieved);
  EXPECT_EQ(read.recipe_json, ReadSecondaryCapture(capture).recipe_json);
  EXPECT_EQ(read.source_series_uid, stamp.series_uid);
  EXPECT_EQ(read.patient_id, stamp.patient_id);
  orthanc.Stop();
}

}  // namespace
}  // namespace cinevol::pacs

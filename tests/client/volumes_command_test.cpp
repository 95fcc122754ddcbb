// `cinevol volumes ...` and `cinevol status` as users run them, against a
// real local server with a temporary data root: readable tables, proto3 JSON
// for scripts, the server's refusals as one line and exit 3; and session
// scripts whose session line loads or uploads its volume.
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::pair<int, std::string> Cinevol(const ScratchDir& scratch, const std::vector<std::string>& args) {
  return RunProgram(CliPath(), args, scratch / "cinevol.log", 120s);
}

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// One line on stderr, no stack trace.
void ExpectCleanError(const std::pair<int, std::string>& result, int code, const std::string& text) {
  EXPECT_EQ(result.first, code) << result.second;
  EXPECT_TRUE(Has(result.second, text)) << "expected '" << text << "' in: " << result.second;
  EXPECT_FALSE(Has(result.second, "terminate")) << result.second;
  EXPECT_LE(std::count(result.second.begin(), result.second.end(), '\n'), 1) << result.second;
}

// `json` parsed into `message`; a failure names what protobuf found wrong.
template <class Message>
Message ParseJson(const std::string& json) {
  Message message;
  const auto status = google::protobuf::util::JsonStringToMessage(json, &message);
  EXPECT_TRUE(status.ok()) << status.message() << " in: " << json;
  return message;
}

// A server whose data root holds sub/small.nrrd (16^3), with outside.nrrd
// beside the root, and the command-line arguments that reach it.
struct VolumesServer {
  ScratchDir scratch;
  fs::path root = scratch / "data";
  std::unique_ptr<ServerProcess> server;

  VolumesServer() {
    fs::create_directories(root / "sub");
    WriteSmallNrrd(root / "sub" / "small.nrrd");
    WriteSmallNrrd(scratch / "outside.nrrd");
    server = std::make_unique<ServerProcess>(scratch.path(), std::vector<std::string>{"--data-root", root.string()});
  }
  // `cinevol ARGS... --server ADDR`.
  std::pair<int, std::string> Run(std::vector<std::string> args) const {
    args.insert(args.end(), {"--server", server->address(), "--connect-timeout", "10"});
    return Cinevol(scratch, args);
  }
};

TEST(VolumesCommand, ListPrintsATableAndJson) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  auto [code, output] = s.Run({"volumes", "list"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(
      std::regex_search(output, std::regex("^ID +KIND +DEFAULT PRESET +DIMS +SPACING +VALUES +MEMORY +SESSIONS")))
      << output;
  EXPECT_TRUE(std::regex_search(output, std::regex("\nphantom:head\\?size=48 .* 48x48x48 .* [0-9.]+ [KM]iB +0\n")))
      << output;

  std::tie(code, output) = s.Run({"volumes", "list", "--json"});
  ASSERT_EQ(code, 0) << output;
  const auto list = ParseJson<v1::ListVolumesResponse>(output);
  ASSERT_EQ(list.volumes_size(), 1) << output;
  EXPECT_EQ(list.volumes(0).id(), "phantom:head?size=48");
  EXPECT_TRUE(Has(output, "\"sessions\":0")) << "every field, zero or not: " << output;
}

TEST(VolumesCommand, LoadsAPathUnderTheDataRootsAndRefusesOthers) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  auto [code, output] = s.Run({"volumes", "load", "sub/small.nrrd"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "id:              small\n")) << output;
  EXPECT_TRUE(Has(output, "dimensions:      16x16x16 voxels\n")) << output;
  std::tie(code, output) = s.Run({"volumes", "load", (s.root / "sub" / "small.nrrd").string(), "--json"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_EQ(ParseJson<v1::VolumeInfo>(output).id(), "small") << "loaded once, by its absolute path too";

  ExpectCleanError(s.Run({"volumes", "load", "../outside.nrrd"}), 3, "PERMISSION_DENIED");
  EXPECT_TRUE(Has(s.Run({"volumes", "load", "../outside.nrrd"}).second, "outside")) << "names the problem";
  ExpectCleanError(s.Run({"volumes", "load", "sub/missing.nrrd"}), 3, "does not exist");
}

// A DICOM series with a missing slice: refused by name, then loaded
// resampled with --resample-uneven, its note saying so.
TEST(VolumesCommand, AnUnevenSeriesLoadsResampledWhenAsked) {
  CINEVOL_REQUIRE_SHARED_DATA();
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  const fs::path series = s.root / "uneven";
  fs::create_directories(series);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(SharedData() / "mr-chest-dicom-seg3d")) {
    if (e.path().filename() != "README.txt") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  files.erase(files.begin() + 7);
  for (const fs::path& f : files) fs::copy_file(f, series / f.filename());
  auto [code, output] = s.Run({"volumes", "load", "uneven"});
  EXPECT_EQ(code, 3) << output;
  EXPECT_TRUE(Has(output, "uneven slice spacing")) << output;
  EXPECT_TRUE(Has(output, "(--resample-uneven)")) << output;
  std::tie(code, output) = s.Run({"volumes", "load", "uneven", "--resample-uneven"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "resampled onto an even grid of 2.5 mm")) << output;
}

TEST(VolumesCommand, UploadsSelfContainedFilesOnly) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  WriteSmallNrrd(s.scratch / "mine.nrrd");
  auto [code, output] = s.Run({"volumes", "upload", (s.scratch / "mine.nrrd").string(), "--json"});
  ASSERT_EQ(code, 0) << output;
  const auto uploaded = ParseJson<v1::VolumeInfo>(output);
  EXPECT_EQ(uploaded.id(), "mine");
  EXPECT_EQ(uploaded.source(), "upload:mine.nrrd");
  EXPECT_EQ(uploaded.dims().z(), 16u);

  std::ofstream(s.scratch / "detached.nrrd") << "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"
                                                "data file: " << (s.scratch / "outside.nrrd").string() << "\n\n";
  ExpectCleanError(s.Run({"volumes", "upload", (s.scratch / "detached.nrrd").string()}), 3,
                   "uploads must be self-contained");
  ExpectCleanError(s.Run({"volumes", "upload", (s.scratch / "absent.nrrd").string()}), 2, "absent.nrrd");
}

TEST(VolumesCommand, DescribeShowsEveryField) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  ASSERT_EQ(s.Run({"volumes", "load", "sub/small.nrrd", "--json"}).first, 0);
  auto [code, output] = s.Run({"volumes", "describe", "small"});
  ASSERT_EQ(code, 0) << output;
  for (const char* field : {"id:              small\n", "source:          ", "modality:        ", "value unit:      ",
                            "kind:            ", "default preset:  ", "dimensions:      16x16x16 voxels\n",
                            "spacing:         1x1x1 mm\n", "extent:          16x16x16 mm\n", "origin:          ",
                            "value range:     0 .. 1500\n", "memory:          ", "sessions:        0\n",
                            "histogram:       "}) {
    EXPECT_TRUE(Has(output, field)) << field << " missing from:\n" << output;
  }
  // The server's judgement and its histogram, drawn in 64 columns between its ends.
  EXPECT_TRUE(std::regex_search(output, std::regex("kind:            (CT_HU|CT_SCALED|MR|OTHER)"))) << output;
  EXPECT_TRUE(std::regex_search(output, std::regex("default preset:  [a-z]"))) << output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      output, m, std::regex("histogram:       256 bins, log scale\n +\\|(.*)\\|\n +[-0-9.e+]+ +[-0-9.e+]+\n")))
      << output;
  const std::string line = m[1];
  EXPECT_EQ(std::count_if(line.begin(), line.end(), [](char c) { return (c & 0xC0) != 0x80; }), 64)
      << "64 characters (UTF-8 blocks or spaces): " << line;
  EXPECT_TRUE(Has(line, "█")) << "the tallest column reaches the top: " << line;

  std::tie(code, output) = s.Run({"volumes", "describe", "small", "--json"});
  ASSERT_EQ(code, 0) << output;
  const auto info = ParseJson<v1::VolumeInfo>(output);
  EXPECT_EQ(info.histogram().counts_size(), 256);
  EXPECT_EQ(info.max_value(), 1500);
  ExpectCleanError(s.Run({"volumes", "describe", "no-such-volume"}), 3, "NOT_FOUND");
}

TEST(VolumesCommand, UnloadFreesAVolume) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  ASSERT_EQ(s.Run({"volumes", "load", "sub/small.nrrd", "--json"}).first, 0);
  auto [code, output] = s.Run({"volumes", "unload", "small"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Has(output, "unloaded small")) << output;
  EXPECT_FALSE(Has(s.Run({"volumes", "list"}).second, "small")) << "gone from the list";
  ExpectCleanError(s.Run({"volumes", "unload", "small"}), 3, "NOT_FOUND");
}

TEST(VolumesCommand, StatusPrintsTablesAndJson) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  auto [code, output] = s.Run({"status"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(std::regex_search(output, std::regex("^cinevol-server \\S+ at 127\\.0\\.0\\.1:[0-9]+, up [0-9]+ s; "
                                                   "encoder: 2 threads, [0-9]+ frames queued\n")))
      << output;
  EXPECT_TRUE(
      std::regex_search(output, std::regex("\nDEVICE +SESSIONS +VOLUMES .*\ncpu[^\n]* +0 +0 \\(0 B\\) +- +- +0 +"
                                           "[0-9.]+ s\n")))
      << output;
  EXPECT_TRUE(Has(output, "\nno sessions\n")) << output;
  EXPECT_TRUE(Has(output, "\nno volume copies on the devices\n")) << output;
  EXPECT_TRUE(Has(output, "\nphantom:head?size=48 ")) << output;

  std::tie(code, output) = s.Run({"status", "--json"});
  ASSERT_EQ(code, 0) << output;
  const auto status = ParseJson<v1::ServerStatus>(output);
  EXPECT_FALSE(status.version().empty()) << output;
  ASSERT_EQ(status.devices_size(), 1) << output;
  EXPECT_EQ(status.devices(0).name().rfind("cpu", 0), 0u) << status.devices(0).name();
  EXPECT_EQ(status.encode_threads(), 2u);
  EXPECT_EQ(status.volumes_size(), 1);
}

TEST(VolumesCommand, AServerThatIsDownExitsThreeInBoundedTime) {
  ScratchDir scratch;
  const std::string address = "127.0.0.1:" + std::to_string(FreePort());
  for (const std::vector<std::string>& command :
       {std::vector<std::string>{"volumes", "list"}, {"volumes", "describe", "x"}, {"status", "--json"}}) {
    std::vector<std::string> args = command;
    args.insert(args.end(), {"--server", address, "--connect-timeout", "1"});
    const auto start = std::chrono::steady_clock::now();
    ExpectCleanError(Cinevol(scratch, args), 3, "cannot reach cinevol-server at " + address);
    EXPECT_LT(std::chrono::steady_clock::now() - start, 15s) << command[0];
  }
}

// The script's session line loads or uploads the volume it plays on, and
// takes the volume's default preset when it names none.
TEST(VolumesCommand, ScriptSessionsLoadOrUploadTheirVolume) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  fs::create_directories(s.scratch / "scripts" / "local");
  WriteSmallNrrd(s.scratch / "scripts" / "local" / "mine.nrrd");
  const std::string events = R"(
{"at": 0.0, "orbit": {"degrees": 20, "seconds": 0.2, "hz": 10}}
)";
  const std::string session = R"("viewport": {"width": 48, "height": 32}, "stream": {"targetSpp": 4}}})";
  std::ofstream(s.scratch / "scripts" / "upload.jsonl") << R"({"session": {"upload": "local/mine.nrrd", )" << session
                                                         << events;
  std::ofstream(s.scratch / "scripts" / "load.jsonl") << R"({"session": {"load": "sub/small.nrrd", )" << session
                                                       << events;
  const std::string out = (s.scratch / "played").string();
  for (const char* script : {"upload.jsonl", "load.jsonl"}) {
    const auto [code, output] =
        s.Run({"play", "--script", (s.scratch / "scripts" / script).string(), "--out", out, "--timeout", "60"});
    ASSERT_EQ(code, 0) << script << ": " << output;
    EXPECT_TRUE(Has(output, "3 events")) << output;
  }
  const std::string list = s.Run({"volumes", "list"}).second;
  EXPECT_TRUE(Has(list, "\nmine ")) << list;
  EXPECT_TRUE(Has(list, "\nsmall ")) << list;

  std::ofstream(s.scratch / "scripts" / "both.jsonl") << R"({"session": {"load": "sub/small.nrrd", "volume": "x"}})";
  ExpectCleanError(s.Run({"play", "--script", (s.scratch / "scripts" / "both.jsonl").string()}), 2,
                   "both.jsonl line 1: session: name the volume once");
  std::ofstream(s.scratch / "scripts" / "gone.jsonl") << R"({"session": {"upload": "local/gone.nrrd"}})";
  ExpectCleanError(s.Run({"play", "--script", (s.scratch / "scripts" / "gone.jsonl").string()}), 2,
                   "session.upload: ");
}

// Segmentations from the command line: `volumes labels` on the server's disk
// or uploaded, the names shown; a script's session line loads one and its
// events style the labels. (The small volume's own values, 0 to 1500 by
// hundreds, serve as labels on its grid.)
TEST(VolumesCommand, LabelsLoadOrUploadAndScriptsStyleThem) {
  VolumesServer s;
  ASSERT_TRUE(s.server->running()) << s.server->Log();
  std::ofstream(s.root / "sub" / "names.tsv") << "0\tnothing\n100\tone hundred\n";
  ASSERT_EQ(s.Run({"volumes", "load", "sub/small.nrrd"}).first, 0);
  const auto [code, loaded] = s.Run({"volumes", "labels", "small", "sub/small.nrrd", "--table", "sub/names.tsv"});
  ASSERT_EQ(code, 0) << loaded;
  EXPECT_TRUE(Has(loaded, "labels:          16 values")) << loaded;
  EXPECT_TRUE(Has(loaded, "one hundred")) << loaded;

  WriteSmallNrrd(s.scratch / "mine.nrrd");
  std::ofstream(s.scratch / "bad.tsv") << "0\tnothing\n100 one hundred\n";
  const auto uploaded = s.Run({"volumes", "upload", (s.scratch / "mine.nrrd").string(), "--json"});
  ASSERT_EQ(uploaded.first, 0) << uploaded.second;
  const std::string id = ParseJson<v1::VolumeInfo>(uploaded.second).id();
  ExpectCleanError(s.Run({"volumes", "labels", id, (s.scratch / "mine.nrrd").string(), "--table",
                          (s.scratch / "bad.tsv").string(), "--upload"}),
                   3, "header.label_table line 2");
  const auto json = s.Run({"volumes", "labels", id, (s.scratch / "mine.nrrd").string(), "--upload", "--json"});
  ASSERT_EQ(json.first, 0) << json.second;
  EXPECT_EQ(ParseJson<v1::VolumeInfo>(json.second).labels().names_size(), 16);

  std::ofstream(s.scratch / "labels.jsonl")
      << R"({"session": {"load": "sub/small.nrrd", "labels": {"load": "sub/small.nrrd", "table": "sub/names.tsv"}, )"
      << R"("viewport": {"width": 48, "height": 32}, "stream": {"targetSpp": 4}}})" << "\n"
      << R"({"at": 0.1, "labels": {"showUnlisted": false, "styles": [{"value": 100}]}})" << "\n";
  const auto played = s.Run({"play", "--script", (s.scratch / "labels.jsonl").string(), "--out",
                             (s.scratch / "played").string(), "--timeout", "60"});
  EXPECT_EQ(played.first, 0) << played.second;
  EXPECT_TRUE(Has(played.second, "1 events")) << played.second;
}

}  // namespace
}  // namespace cinevol::testing

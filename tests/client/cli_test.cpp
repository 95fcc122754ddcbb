// The `cinevol` subcommands as users run them, against a real local server:
// demo, play, snapshot and loadtest, and their errors (server down, refused
// token, bad script, refused volume): a clear message and a non-zero exit.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::pair<int, std::string> Cinevol(const ScratchDir& scratch, const std::vector<std::string>& args) {
  return RunProgram(CliPath(), args, scratch / "cinevol.log", 180s);
}

void WriteText(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

int CountLines(const fs::path& path) {
  std::ifstream in(path);
  int n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

// A short script on the test server's phantom.
const char* kScript =
    R"({"session": {"volume": "phantom:head?size=48", "viewport": {"width": 96, "height": 64}, "stream": {"targetSpp": 16}}}
{"at": 0.0, "orbit": {"degrees": 30, "seconds": 0.5, "hz": 20}}
{"at": 0.6, "transferFunction": {"preset": "ct-soft-tissue"}}
)";

TEST(CinevolCli, DemoRunsThroughARealServer) {
  ScratchDir scratch;
  const auto out = scratch / "demo";
  const auto [code, output] = Cinevol(scratch, {"demo", "--backend", "cpu", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("starting cinevol-server"), std::string::npos) << output;
  EXPECT_NE(output.find("fps"), std::string::npos) << "progress and summary";
  EXPECT_NE(output.find("latency p50/p95/p99"), std::string::npos) << output;
  EXPECT_NE(output.find("refined to "), std::string::npos) << output;
  EXPECT_NE(output.find("% estimated error or 64 spp"), std::string::npos) << "a CPU refines to 64: " << output;
  // The shared data's CT where it lies beside the checkout, else the built-in phantom.
  const bool shared_ct = fs::is_regular_file(SharedData() / "ct-body-totalsegmentator/example_ct.nii.gz");
  EXPECT_NE(output.find(shared_ct ? "example_ct.nii.gz" : "the built-in head phantom"), std::string::npos) << output;
  const ImageRgb8 sheet = ReadPng(out / "contact-sheet.png");
  EXPECT_GT(sheet.width, 400);
  int frames = 0;
  for (const auto& entry : fs::directory_iterator(out / "frames")) frames += entry.path().extension() == ".jpg";
  EXPECT_GT(frames, 20);
  EXPECT_GT(CountLines(out / "frames.csv"), frames);
  EXPECT_TRUE(fs::exists(out / "summary.txt"));
  EXPECT_TRUE(fs::exists(out / "final.jpg"));
  // The demo stopped its server: nothing listens on its port any more.
  int port = 0;
  std::ifstream(out / "server.port") >> port;
  ASSERT_GT(port, 0);
  ClientOptions options;
  options.address = "127.0.0.1:" + std::to_string(port);
  options.connect_timeout = 500ms;
  EXPECT_THROW(Client{options}, RpcError);
}

TEST(CinevolCli, PlayAndSnapshotAgainstAServer) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  WriteText(scratch / "script.jsonl", kScript);
  const auto out = scratch / "played";
  auto [code, output] =
      Cinevol(scratch, {"play", "--server", server.address(), "--script", (scratch / "script.jsonl").string(), "--out",
                        out.string(), "--target-spp", "12", "--error-target", "0", "--final-format", "png"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("12 events"), std::string::npos) << output;  // 11 orbit cameras and the edit
  EXPECT_EQ(output.rfind("session ", 0), 0u) << "the session's id comes first, for `cinevol share`: " << output;
  std::ifstream csv(out / "frames.csv");
  std::string header, line, last;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("frame_id,received_s,width,height,accumulated_spp,final,last_event_seq", 0), 0u);
  int rows = 0;
  while (std::getline(csv, line)) last = line, ++rows;
  EXPECT_GT(rows, 5);
  EXPECT_NE(last.find(",96,64,"), std::string::npos) << last;
  EXPECT_NE(last.find(",1,12,"), std::string::npos) << "the last frame is final and answers the last event: " << last;
  EXPECT_NE(last.find(",12,1,12,"), std::string::npos) << "--target-spp 12 caps the script's refinement: " << last;
  ASSERT_EQ(last.substr(last.size() - 4), ".png") << "--final-format png: " << last;
  EXPECT_EQ(ReadPng(out / "frames" / last.substr(last.rfind(',') + 1)).width, 96);
  EXPECT_TRUE(Eventually([&] { return server.Connect().Status().sessions().empty(); }, 10s))
      << "play closes its session";

  std::tie(code, output) =
      Cinevol(scratch, {"snapshot", "--server", server.address(), "--volume", "phantom:head?size=48", "--width", "80",
                        "--height", "60", "--spp", "8", "--out", (scratch / "still.png").string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_EQ(ReadPng(scratch / "still.png").width, 80);
  std::tie(code, output) = Cinevol(scratch, {"snapshot", "--server", server.address(), "--width", "80", "--height",
                                             "60", "--spp", "4", "--out", (scratch / "still.exr").string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_EQ(ReadExr(scratch / "still.exr").height, 60);
}

std::vector<std::string> CsvLines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A script's slice and pick lines (docs/client.md): the slice in slices/ at
// the volume's own grid, a pick on the head and one past it in picks.csv,
// each made once the events before it are applied: the last pick sees the
// head from its left, though a server taking one event a second reads that
// camera event a quarter of a second after the one before (it paces its
// reads). A slice the server refuses ends the run naming its line.
TEST(CinevolCli, PlayWritesTheScriptsSlicesAndPicks) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-events-per-second", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  WriteText(
      scratch / "reading.jsonl",
      R"({"session": {"volume": "phantom:head?size=48", "preset": "ct-bone", "viewport": {"width": 96, "height": 64}, "stream": {"targetSpp": 4}}}
{"at": 0.0, "camera": {"view": "ANTERIOR"}}
{"at": 0.1, "slice": {"axis": "coronal", "positionMm": 0.5, "windowPreset": "bone", "out": "coronal.png"}}
{"at": 0.1, "pick": {"x": 48, "y": 32}}
{"at": 0.2, "pick": {"x": 0.5, "y": 0.5, "threshold": 0.5}}
{"at": 0.2, "render": {"maxBounces": 4}}
{"at": 0.2, "camera": {"view": "LEFT"}}
{"at": 0.2, "pick": {"x": 48, "y": 32}}
)");
  const auto out = scratch / "played";
  auto [code, output] = Cinevol(scratch, {"play", "--server", server.address(), "--script",
                                          (scratch / "reading.jsonl").string(), "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("wrote 1 slices to"), std::string::npos) << output;
  EXPECT_NE(output.find("wrote 3 picks to"), std::string::npos) << output;
  const ImageRgb8 coronal = ReadPng(out / "slices" / "coronal.png");
  EXPECT_EQ(coronal.width, 48) << "one pixel per voxel: x across";
  EXPECT_EQ(coronal.height, 48) << "z down";

  const std::vector<std::string> picks = CsvLines(out / "picks.csv");
  ASSERT_EQ(picks.size(), 4u) << output;
  EXPECT_EQ(picks[0], "line,at,x,y,hit,lps_x_mm,lps_y_mm,lps_z_mm,value,label_value,label_name");
  const std::regex hit("([0-9]+),([0-9.]+),48,32,1,([-0-9.e]+),([-0-9.e]+),([-0-9.e]+),([-0-9.e]+),,");
  std::smatch m;
  ASSERT_TRUE(std::regex_match(picks[1], m, hit)) << picks[1];
  EXPECT_EQ(m[1], "4");
  EXPECT_EQ(m[2], "0.1");
  EXPECT_LT(std::stod(m[4]), -5) << "seen from the front, the hit is on the anterior (-y) side: " << picks[1];
  EXPECT_GT(std::stod(m[6]), 100) << "ct-bone stops on bone, far above water's 0 HU: " << picks[1];
  EXPECT_EQ(picks[2], "5,0.2,0.5,0.5,0,,,,,,") << "the corner's ray passes the head";
  ASSERT_TRUE(std::regex_match(picks[3], m, hit)) << picks[3];
  EXPECT_EQ(m[1], "8");
  EXPECT_GT(std::stod(m[3]), 5) << "after the LEFT view: on the patient's left (+x) side: " << picks[3];

  WriteText(scratch / "refused.jsonl",
            R"({"session": {"volume": "phantom:head?size=48", "viewport": {"width": 96, "height": 64}}}
{"at": 0.1, "slice": {"axis": "coronal", "windowPreset": "soup", "out": "soup.png"}}
)");
  std::tie(code, output) = Cinevol(scratch, {"play", "--server", server.address(), "--script",
                                             (scratch / "refused.jsonl").string(), "--out", out.string()});
  EXPECT_EQ(code, 3) << output;
  EXPECT_NE(output.find("INVALID_ARGUMENT: script line 2: slice: window_preset: 'soup'"), std::string::npos) << output;
  EXPECT_TRUE(Eventually([&] { return server.Connect().Status().sessions().empty(); }, 10s))
      << "play closes its session";
}

TEST(CinevolCli, LoadtestReportsJsonForScripts) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  // Slice and pick lines are skipped: a load test measures the stream.
  WriteText(scratch / "script.jsonl", std::string(kScript) + R"({"at": 0.7, "slice": {"out": "axial.png"}}
{"at": 0.7, "pick": {"x": 48, "y": 32}}
)");
  const auto [code, output] =
      Cinevol(scratch, {"loadtest", "--server", server.address(), "--sessions", "2", "--seconds", "2", "--script",
                        (scratch / "script.jsonl").string(), "--json"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("\"per_session\": ["), std::string::npos) << output;
  EXPECT_NE(output.find("\"errors\": {}"), std::string::npos) << output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(output, m, std::regex("\"overall\": \\{\"frames\": ([0-9]+)"))) << output;
  EXPECT_GT(std::stoi(m[1]), 4);
  EXPECT_TRUE(std::regex_search(output, std::regex("\"latency_ms\": \\{\"p50\": [0-9.]+"))) << output;
}

TEST(CinevolCli, LoadtestCountsFramesRenderedSmallerWhileMoving) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const auto [code, output] =
      Cinevol(scratch, {"loadtest", "--server", server.address(), "--sessions", "1", "--seconds", "2", "--width", "64",
                        "--height", "48", "--event-hz", "30", "--interactive-frame-ms", "0.001", "--json"});
  ASSERT_EQ(code, 0) << output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(output, m, std::regex("\"smaller_frames\": ([0-9]+)"))) << output;
  EXPECT_GT(std::stoi(m[1]), 0) << "no frame meets the budget: the orbit steps down to smaller frames";
}

// One line on stderr, no stack trace.
void ExpectCleanError(const std::pair<int, std::string>& result, int code, const std::string& text) {
  EXPECT_EQ(result.first, code) << result.second;
  EXPECT_NE(result.second.find(text), std::string::npos) << result.second;
  EXPECT_EQ(result.second.find("terminate"), std::string::npos) << result.second;
  EXPECT_LE(std::count(result.second.begin(), result.second.end(), '\n'), 2) << result.second;
}

// The sharing commands are contracts: share prints the secret alone on its
// last line, watch writes frames and frames.csv as play does, revoke ends it.
TEST(CinevolCli, ShareWatchSharesAndRevoke) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client owner = server.Connect();
  const auto created = owner.CreateSession(SmallSession());
  auto stream = owner.Attach(created.session_id());
  ASSERT_TRUE(WaitFinal(*stream)) << stream->status().error_message();
  const std::string& id = created.session_id();

  auto [code, output] = Cinevol(scratch, {"share", id, "--link", "--expires", "15m", "--server", server.address()});
  ASSERT_EQ(code, 0) << output;
  std::string secret = output.substr(0, output.find_last_not_of('\n') + 1);
  secret = secret.substr(secret.find_last_of('\n') + 1);
  EXPECT_EQ(secret.rfind("cvg_", 0), 0u) << output;

  const auto out = scratch / "watched";
  std::tie(code, output) = Cinevol(scratch, {"watch", "--server", server.address(), "--grant", secret, "--seconds",
                                             "2", "--out", out.string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("watched anonymous presenting"), std::string::npos) << output;
  EXPECT_GE(CountLines(out / "frames.csv"), 2) << "a header and the newest frame at least";

  std::tie(code, output) = Cinevol(scratch, {"shares", id, "--server", server.address()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("link"), std::string::npos) << output;
  EXPECT_EQ(output.find(secret), std::string::npos) << "a list never shows a secret";
  const std::string grant_id = secret.substr(4, secret.find('_', 4) - 4);
  std::tie(code, output) = Cinevol(scratch, {"revoke", id, grant_id, "--server", server.address()});
  ASSERT_EQ(code, 0) << output;
  std::tie(code, output) = Cinevol(scratch, {"watch", "--server", server.address(), "--grant", secret, "--seconds",
                                             "2", "--out", (scratch / "again").string()});
  EXPECT_NE(code, 0);
  EXPECT_NE(output.find("PERMISSION_DENIED"), std::string::npos) << output;
  std::tie(code, output) = Cinevol(scratch, {"share", id, "--server", server.address()});
  EXPECT_NE(code, 0) << "neither --principal nor --link";
  EXPECT_NE(output.find("--principal P or --link"), std::string::npos) << output;
}

TEST(CinevolCli, ErrorsAreClearWithANonZeroExit) {
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "good-token alice\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  WriteText(scratch / "script.jsonl", kScript);
  const std::string script = (scratch / "script.jsonl").string();

  ExpectCleanError(
      Cinevol(scratch, {"loadtest", "--server", "127.0.0.1:1", "--connect-timeout", "1", "--seconds", "1"}), 3,
      "cannot reach cinevol-server at 127.0.0.1:1");
  ExpectCleanError(Cinevol(scratch, {"play", "--server", server.address(), "--script", script}), 3, "UNAUTHENTICATED");
  ExpectCleanError(Cinevol(scratch, {"play", "--server", server.address(), "--token", "bad", "--script", script}), 3,
                   "not valid");

  // A script with a misspelt field on line 3, one with a bad value (caught by the server) on line 2.
  WriteText(scratch / "typo.jsonl", R"({"session": {"volume": "phantom:head?size=48"}}
{"at": 0, "camera": {"view": "LEFT"}}
{"at": 1, "camera": {"fovYdeg": 20}}
)");
  ExpectCleanError(Cinevol(scratch, {"play", "--server", server.address(), "--token", "good-token", "--script",
                                     (scratch / "typo.jsonl").string()}),
                   2, "typo.jsonl line 3");
  EXPECT_NE(Cinevol(scratch, {"play", "--script", (scratch / "typo.jsonl").string()}).second.find("fovYdeg"),
            std::string::npos);
  WriteText(scratch / "bad-value.jsonl",
            R"({"session": {"volume": "phantom:head?size=48", "viewport": {"width": 96, "height": 64}}}
{"at": 0.2, "camera": {"view": "LEFT", "fovYDeg": 500}}
)");
  ExpectCleanError(Cinevol(scratch, {"play", "--server", server.address(), "--token", "good-token", "--script",
                                     (scratch / "bad-value.jsonl").string(), "--out", (scratch / "o").string()}),
                   3, "script line 2: camera.fovYDeg");
  WriteText(scratch / "missing.jsonl", R"({"session": {"volume": "no-such-volume"}})");
  ExpectCleanError(Cinevol(scratch, {"play", "--server", server.address(), "--token", "good-token", "--script",
                                     (scratch / "missing.jsonl").string()}),
                   3, "NOT_FOUND");
  ExpectCleanError(Cinevol(scratch, {"snapshot", "--server", server.address(), "--token", "good-token", "--out",
                                     (scratch / "x.gif").string()}),
                   2, "use .png or .exr");
}

// `cinevol snapshot` opens a session of its own and never attaches to it;
// a server that reaps such sessions after a second must not reap it while
// its still renders (about three seconds here).
TEST(CinevolCli, SnapshotOutlivesTheUnattachedSessionLimit) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--unattached-session-seconds", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const std::string probe = client.CreateSession(SmallSession("ct-bone", 96, 64)).session_id();
  const int spp = SppForSeconds(client, probe, 3.0);
  client.CloseSession(probe);
  const auto [code, output] =
      Cinevol(scratch, {"snapshot", "--server", server.address(), "--volume", "phantom:head?size=48", "--preset",
                        "ct-bone", "--width", "96", "--height", "64", "--spp", std::to_string(spp), "--out",
                        (scratch / "still.png").string()});
  ASSERT_EQ(code, 0) << output << server.Log();
  // Progress is newest-wins: the first line a client prints may already count a step.
  EXPECT_TRUE(std::regex_search(output, std::regex("snapshot: [0-9]+/" + std::to_string(spp) + " spp")))
      << "progress: " << output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(output, m, std::regex("rendered in ([0-9.]+) s"))) << output;
  EXPECT_GT(std::stod(m[1]), 1.0) << "not longer than the limit: " << output;
  EXPECT_EQ(ReadPng(scratch / "still.png").width, 96);
}

TEST(CinevolCli, SnapshotTimeoutSaysWhatRanOutAndNamesTheFlags) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const auto result = Cinevol(scratch, {"snapshot", "--server", server.address(), "--width", "96", "--height", "64",
                                        "--spp", "16384", "--timeout", "1", "--out", (scratch / "still.png").string()});
  ExpectCleanError(result, 3, "DEADLINE_EXCEEDED: the snapshot did not finish within its timeout of 1 s");
  EXPECT_NE(result.second.find("--timeout S"), std::string::npos) << result.second;
  EXPECT_NE(result.second.find("--spp"), std::string::npos) << result.second;
  Client client = server.Connect();
  EXPECT_TRUE(Eventually([&] { return client.Status().sessions().empty(); }, 10s)) << "its session was left open";
}

// Bad flags are bad input: exit 2 as docs/client.md says, not CLI11's 105 or 109.
TEST(CinevolCli, FlagErrorsExitTwo) {
  ScratchDir scratch;
  EXPECT_EQ(Cinevol(scratch, {"snapshot", "--no-such-flag"}).first, 2);
  EXPECT_EQ(Cinevol(scratch, {"snapshot", "--spp", "0", "--out", "x.png"}).first, 2);
  EXPECT_EQ(Cinevol(scratch, {"snapshot"}).first, 2) << "--out is required";
  EXPECT_EQ(Cinevol(scratch, {"no-such-command"}).first, 2);
  EXPECT_EQ(Cinevol(scratch, {"status", "extra"}).first, 2);
  EXPECT_EQ(Cinevol(scratch, {"snapshot", "--help"}).first, 0);
  EXPECT_EQ(RunProgram(ServerPath(), {"--no-such-flag"}, scratch / "server.log").first, 2);
  EXPECT_EQ(RunProgram(ServerPath(), {"--max-sessions", "0"}, scratch / "server.log").first, 2);
}

// A scene file without lights renders lit (the volume's default lights),
// offline and on a server, and the command says so on stderr.
TEST(CinevolCli, ASceneWithoutLightsIsLitByTheVolumesDefaultLights) {
  ScratchDir scratch;
  WriteText(scratch / "unlit.json",
            R"({"volume": {"phantom": {"kind": "HEAD", "size": 48}}, "transferFunction": {"preset": "ct-bone"},
                "camera": {"view": "ANTERIOR"}, "render": {"width": 64, "height": 48, "spp": 4}})");
  auto [code, output] = Cinevol(scratch, {"render", "--scene", (scratch / "unlit.json").string(), "--out",
                                          (scratch / "offline.png").string(), "--spp", "8", "--backend", "cpu"});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("no lights"), std::string::npos) << output;
  EXPECT_GT(MeanLevel(ReadPng(scratch / "offline.png")), 10) << "black: unlit";

  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  std::tie(code, output) =
      Cinevol(scratch, {"snapshot", "--server", server.address(), "--scene", (scratch / "unlit.json").string(),
                        "--width", "64", "--height", "48", "--spp", "8", "--out", (scratch / "served.png").string()});
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("unlit.json: no lights: the session takes the volume's default lights"), std::string::npos)
      << output;
  EXPECT_GT(MeanLevel(ReadPng(scratch / "served.png")), 10) << "black: unlit";
}

}  // namespace
}  // namespace cinevol::testing

// cinevol-viewer end to end under Xvfb: a real window against a real CPU
// server on loopback, driven by session scripts with UI actions; the tests
// read its screenshots (and the layout file written beside each: where the
// frame, the panels and the stats overlay are).
#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <set>

#include "encode/image_codecs.h"
#include "pacs/orthanc_process.h"
#include "pacs/stamped_series.h"
#include "scene/scene_file.h"
#include "service/server_process.h"
#include "service/service_test_support.h"
#include "sharing_calls.h"
#include "support/shell_command.h"
#include "support/test_paths.h"
#include "support/time_series_nifti.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;

#ifdef CINEVOL_VIEWER_PATH
constexpr const char* kViewer = CINEVOL_VIEWER_PATH;
#else
constexpr const char* kViewer = "";
#endif

#define CINEVOL_REQUIRE_VIEWER()                                                                          \
  do {                                                                                                    \
    if (!fs::exists(kViewer)) GTEST_SKIP() << "cinevol-viewer was not built (libsdl2-dev, libimgui-dev)"; \
    if (std::system("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run not found (xvfb)"; \
  } while (0)

struct ViewerRun {
  int exit_code = -1;
  std::string output;
};

// xvfb-run's arguments for the viewer on a virtual display of its own,
// 640x400, at most 90 s. xvfb-run's --auto-servernum races when tests run
// side by side, so each run draws a display number whose lock file and
// socket are absent, starting at a random place.
std::vector<std::string> XvfbRunArgs(const std::vector<std::string>& viewer_args) {
  static std::mt19937 draw{std::random_device{}()};
  int display = 100 + int(draw() % 800);
  for (int tries = 0; tries < 800; ++tries, display = 100 + (display - 99) % 800) {
    if (!fs::exists(fmt::format("/tmp/.X{}-lock", display)) && !fs::exists(fmt::format("/tmp/.X11-unix/X{}", display)))
      break;
  }
  // The viewer's status is printed from inside: xvfb-run exits 5, losing
  // it, when it cannot remove its temporary folder afterwards (seen on CI
  // machines under load).
  std::vector<std::string> all{"-n", std::to_string(display), "-s", "-screen 0 1024x768x24", "sh", "-c",
                               "timeout 90 \"$0\" \"$@\"; echo \"cinevol-viewer exited $?\"",
                               kViewer, "--width", "640", "--height", "400"};
  all.insert(all.end(), viewer_args.begin(), viewer_args.end());
  return all;
}

// The viewer's exit status as XvfbRunArgs' wrapper printed it; `fallback`
// (xvfb-run's own) where it did not get that far.
int ViewerExitCode(const std::string& output, int fallback) {
  constexpr std::string_view kExited = "cinevol-viewer exited ";
  const std::size_t at = output.rfind(kExited);
  if (at == std::string::npos) return fallback;
  return std::atoi(output.c_str() + at + kExited.size());
}

ViewerRun RunViewer(const fs::path& scratch, const std::vector<std::string>& args) {
  // Xvfb may not start, seen on the CI machine under load (another run took
  // the display between the check and the start): the harness failing, not
  // the viewer. Run again.
  for (int attempt = 0;; ++attempt) {
    auto [code, output] =
        RunProgram("/usr/bin/xvfb-run", XvfbRunArgs(args), scratch / "viewer.log", std::chrono::seconds(120));
    if (output.find("xvfb-run: error: Xvfb failed to start") != std::string::npos && attempt < 2) continue;
    return {ViewerExitCode(output, code), output};
  }
}

fs::path WriteScript(const fs::path& file, const std::string& text) {
  std::ofstream(file) << text;
  return file;
}

struct Region {
  int x, y, w, h;
};

// A rectangle of the layout file: [x, y, w, h] in screenshot pixels.
Region RegionOf(const google::protobuf::Struct& layout, const std::string& key) {
  const auto& v = layout.fields().at(key).list_value().values();
  return {int(v[0].number_value()), int(v[1].number_value()), int(v[2].number_value()), int(v[3].number_value())};
}

google::protobuf::Struct ReadLayout(const fs::path& png) {
  std::ifstream in(fs::path(png).replace_extension(".layout.json"));
  const std::string json{std::istreambuf_iterator<char>(in), {}};
  google::protobuf::Struct layout;
  EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(json, &layout).ok()) << json;
  return layout;
}

// Mean and standard deviation of the luminance in a region.
std::pair<double, double> Luminance(const ImageRgb8& img, Region r) {
  double sum = 0, sum2 = 0, n = 0;
  for (int y = r.y; y < r.y + r.h && y < img.height; ++y) {
    for (int x = r.x; x < r.x + r.w && x < img.width; ++x) {
      const std::uint8_t* p = &img.bytes[(std::size_t(y) * img.width + x) * 3];
      const double l = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
      sum += l, sum2 += l * l, ++n;
    }
  }
  const double mean = sum / std::max(1.0, n);
  return {mean, std::sqrt(std::max(0.0, sum2 / std::max(1.0, n) - mean * mean))};
}

double MeanDifference(const ImageRgb8& a, const ImageRgb8& b, Region r) {
  EXPECT_TRUE(a.width == b.width && a.height == b.height && r.x + r.w <= a.width && r.y + r.h <= a.height);
  if (a.width != b.width || a.height != b.height || r.x + r.w > a.width || r.y + r.h > a.height) return 0;
  double sum = 0, n = 0;
  for (int y = r.y; y < r.y + r.h; ++y) {
    for (int x = r.x; x < r.x + r.w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = (std::size_t(y) * a.width + x) * 3 + c;
        sum += std::abs(int(a.bytes[i]) - int(b.bytes[i]));
        ++n;
      }
    }
  }
  return sum / std::max(1.0, n);
}

// Pixels of ImGui's blue headers and buttons: the panels are drawn.
int BluePixels(const ImageRgb8& img, Region r) {
  int n = 0;
  for (int y = r.y; y < r.y + r.h && y < img.height; ++y) {
    for (int x = r.x; x < r.x + r.w && x < img.width; ++x) {
      const std::uint8_t* p = &img.bytes[(std::size_t(y) * img.width + x) * 3];
      n += p[2] > 70 && p[2] > p[0] + 30;
    }
  }
  return n;
}

TEST(Viewer, ShowsTheVolumeStatsAndPanelsAndFollowsEdits) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path a = scratch.path() / "a.png", b = scratch.path() / "b.png", c = scratch.path() / "c.png",
                 edited_png = scratch.path() / "edited.png", scene = scratch.path() / "view.json",
                 still = scratch.path() / "still.png", movie = scratch.path() / "orbit.mp4",
                 cut_png = scratch.path() / "cut.png",
                 cut_scene = scratch.path() / "cut.json", saved_cut = scratch.path() / "saved-cut.json";
  // The example scene with a crop that keeps nothing of the head: opened, the
  // view shows the background (lit as before: the lights are the example's).
  v1::Scene cropped = LoadSceneFile(fs::path(CINEVOL_SOURCE_DIR) / "examples" / "ct-bone.json");
  v1::CropBox* box = cropped.mutable_clipping()->mutable_crop_box();
  box->mutable_center()->set_x(5000);
  box->mutable_size()->set_x(10), box->mutable_size()->set_y(10), box->mutable_size()->set_z(10);
  v1::ClipPlane* plane = cropped.mutable_clipping()->add_planes();  // and an oblique plane, capped
  plane->mutable_normal()->set_x(0.6f), plane->mutable_normal()->set_z(0.8f);
  plane->set_cap(true);
  cropped.mutable_render()->set_reconstruction(v1::TRICUBIC);
  SaveSceneFile(cropped, cut_scene);
  const fs::path script =
      WriteScript(scratch.path() / "tour.jsonl",
                  fmt::format(R"({{"session": {{"stream": {{"targetSpp": 8}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.1, "ui": {{"drag": {{"button": "left", "dx": 150, "dy": 0}}}}}}
{{"at": 0.1, "ui": {{"panel": {{"name": "lights", "open": true}}}}}}
{{"at": 0.2, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.3, "ui": {{"movePoint": {{"index": 1, "value": 1200, "opacity": 0.05}}}}}}
{{"at": 0.4, "ui": {{"settle": true}}}}
{{"at": 0.4, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.4, "ui": {{"saveScene": "{}"}}}}
{{"at": 0.4, "ui": {{"snapshot": {{"file": "{}", "spp": 4}}}}}}
{{"at": 0.4, "ui": {{"movie": {{"file": "{}", "seconds": 0.4, "spp": 1}}}}}}
{{"at": 0.45, "ui": {{"panel": {{"name": "clipping", "open": true}}}}}}
{{"at": 0.45, "ui": {{"openScene": "{}"}}}}
{{"at": 0.5, "ui": {{"settle": true}}}}
{{"at": 0.5, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.5, "ui": {{"saveScene": "{}"}}}}
{{"at": 0.6, "ui": {{"resizeWindow": {{"width": 700, "height": 420}}}}}}
)",
                              a.string(), b.string(), edited_png.string(), scene.string(), still.string(),
                              movie.string(), cut_scene.string(), cut_png.string(), saved_cut.string()));
  const ViewerRun run = RunViewer(
      scratch.path(), {"--server", server.address(), "--script", script.string(), "--screenshot", c.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;

  // a, b and the edit share one window size (the resize comes last).
  const Region frame = RegionOf(ReadLayout(a), "frame");
  const ImageRgb8 before = ReadPng(a), orbited = ReadPng(b), edited = ReadPng(edited_png);
  // A rendered volume: not blank, not one colour.
  const auto [mean, spread] = Luminance(before, frame);
  EXPECT_GT(mean, 20) << "the frame area is blank";
  EXPECT_GT(spread, 10) << "the frame area is uniform";
  EXPECT_GT(MeanDifference(before, orbited, frame), 2.0) << "an orbit did not change the view";
  EXPECT_GT(MeanDifference(orbited, edited, frame), 2.0) << "a transfer-function edit did not change the view";
  // The opened scene's crop took the head away, and a saved scene keeps the crop.
  const ImageRgb8 cut = ReadPng(cut_png);
  EXPECT_GT(MeanDifference(edited, cut, frame), 2.0) << "the opened crop did not change the view";
  const auto [cut_mean, cut_spread] = Luminance(cut, frame);
  EXPECT_LT(cut_spread, spread) << "the cropped view still shows the head";
  EXPECT_GT(cut_mean, 5) << "the cropped view is black: the background is not lit";
  const v1::Scene saved = LoadSceneFile(saved_cut);
  EXPECT_TRUE(saved.clipping().has_crop_box()) << "the saved scene lost the crop";
  ASSERT_EQ(saved.clipping().planes_size(), 1) << "the saved scene lost the clip plane";
  EXPECT_TRUE(saved.clipping().planes(0).cap());
  EXPECT_EQ(saved.render().reconstruction(), v1::TRICUBIC) << "the saved scene lost the reconstruction";
  // The stats overlay is text over a dark box; the panels have their headers.
  const google::protobuf::Struct layout = ReadLayout(c);
  const ImageRgb8 last = ReadPng(c);
  EXPECT_GT(Luminance(last, RegionOf(layout, "stats")).second, 20) << "no stats overlay";
  EXPECT_GT(BluePixels(last, RegionOf(layout, "panel")), 2000) << "no panels";
  EXPECT_GT(layout.fields().at("frameId").number_value(), 1);
  // The scene it saved is one `cinevol render` reads; the snapshot is a PNG.
  EXPECT_NO_THROW(LoadSceneFile(scene));
  EXPECT_GT(ReadPng(still).width, 0);
  // The movie the server made: 10 frames (0.4 s at 25 frames/s) of H.264, written here.
  const CommandResult probed = RunCommand("ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                                          "stream=codec_name,nb_read_frames -of default=nw=1 '" + movie.string() + "'");
  EXPECT_NE(probed.output.find("codec_name=h264"), std::string::npos) << probed.output << run.output;
  EXPECT_NE(probed.output.find("nb_read_frames=10"), std::string::npos) << probed.output;
  // The window was resized: the session's viewport followed the frame area.
  const auto& size = layout.fields().at("frameSize").list_value().values();
  EXPECT_EQ(layout.fields().at("window").list_value().values(0).number_value(), 700);
  EXPECT_EQ(int(size[0].number_value()), RegionOf(layout, "frame").w);
  EXPECT_EQ(int(size[1].number_value()), RegionOf(layout, "frame").h);
}

// Every frame final from the first (targetSpp 1), and the lines due in one
// turn: the screenshot must still show the window before the resize after
// it, and the script must not end on the final frame of the old size.
TEST(Viewer, AScreenshotPrecedesLaterLinesAndTheEndWaitsForTheResizedFrame) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path before = scratch.path() / "before.png", last = scratch.path() / "last.png";
  const fs::path script =
      WriteScript(scratch.path() / "resize.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 1}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 0, "ui": {{"resizeWindow": {{"width": 700, "height": 420}}}}}}
)",
                                                               before.string()));
  const ViewerRun run = RunViewer(
      scratch.path(), {"--server", server.address(), "--script", script.string(), "--screenshot", last.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;

  auto window_width = [](const google::protobuf::Struct& layout) {
    return layout.fields().at("window").list_value().values(0).number_value();
  };
  EXPECT_EQ(window_width(ReadLayout(before)), 640) << "the screenshot shows the resize after it";
  const google::protobuf::Struct layout = ReadLayout(last);
  const auto& size = layout.fields().at("frameSize").list_value().values();
  EXPECT_EQ(window_width(layout), 700);
  EXPECT_EQ(int(size[0].number_value()), RegionOf(layout, "frame").w) << "the script ended before the resized frame";
  EXPECT_EQ(int(size[1].number_value()), RegionOf(layout, "frame").h);
}

TEST(Viewer, ASessionLostWithItsServerIsReplacedWithTheViewersState) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  auto server = std::make_unique<ServerProcess>(scratch.path());
  ASSERT_TRUE(server->running()) << server->Log();
  const int port = server->port();
  const fs::path first = scratch.path() / "first.png", last = scratch.path() / "last.png";
  const fs::path script = WriteScript(scratch.path() / "restart.jsonl", fmt::format(R"({{"session": {{}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.2, "ui": {{"preset": "ct-soft-tissue"}}}}
{{"at": 12, "ui": {{"key": "p"}}}}
)",
                                                                                    first.string()));
  const auto args =
      XvfbRunArgs({"--server", server->address(), "--script", script.string(), "--screenshot", last.string()});
  const pid_t viewer = Spawn("/usr/bin/xvfb-run", args, scratch.path() / "viewer.log");
  ASSERT_GT(viewer, 0);
  // Once the first frame is on screen, the server dies and another takes its port.
  for (int i = 0; i < 600 && !fs::exists(first); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(fs::exists(first)) << "no first frame";
  kill(server->pid(), SIGKILL);
  server.reset();
  const fs::path second_dir = scratch.path() / "second";
  fs::create_directories(second_dir);
  ServerProcess second(second_dir, {}, "cpu", 0, port);
  ASSERT_TRUE(second.running()) << second.Log();
  const int status = WaitExit(viewer, std::chrono::seconds(100));
  std::ifstream log(scratch.path() / "viewer.log");
  const std::string output{std::istreambuf_iterator<char>(log), {}};
  ASSERT_TRUE(status != -1 && WIFEXITED(status)) << output;
  EXPECT_EQ(ViewerExitCode(output, WEXITSTATUS(status)), 0) << output;
  // The new session streams, with the preset the viewer had chosen.
  const google::protobuf::Struct layout = ReadLayout(last);
  EXPECT_EQ(layout.fields().at("state").number_value(), 1) << layout.fields().at("message").string_value();
  EXPECT_GT(layout.fields().at("frameId").number_value(), 0);
  Client client = second.Connect();
  const v1::ServerStatus s = client.Status();
  EXPECT_EQ(s.sessions_size(), 0) << "the viewer closes its session on exit";
}

TEST(Viewer, ServersThatFailOrRefuseAreNamedAndTheViewerExits) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  const fs::path script = WriteScript(scratch.path() / "nothing.jsonl", R"({"session": {}})");
  const fs::path tokens = scratch.path() / "tokens";
  std::ofstream(tokens) << "right-token-0123456789abcdef alice\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", tokens.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  struct Case {
    const char* name;
    std::vector<std::string> args;
    const char* says;
  };
  const std::vector<Case> cases{
      {"down", {"--server", "127.0.0.1:" + std::to_string(FreePort()), "--connect-timeout", "1"}, "cannot reach"},
      {"token", {"--server", server.address(), "--token", "wrong-token"}, "token"},
      {"volume",
       {"--server", server.address(), "--token", "right-token-0123456789abcdef", "--volume", "no-such-volume"},
       "no-such-volume"},
  };
  for (const Case& c : cases) {
    const fs::path shot = scratch.path() / (std::string(c.name) + ".png");
    std::vector<std::string> args = c.args;
    args.insert(args.end(), {"--script", script.string(), "--screenshot", shot.string()});
    const auto start = std::chrono::steady_clock::now();
    const ViewerRun run = RunViewer(scratch.path(), args);
    EXPECT_EQ(run.exit_code, 3) << c.name << ": " << run.output;
    EXPECT_NE(run.output.find(c.says), std::string::npos) << c.name << ": " << run.output;
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(60)) << c.name;
    const google::protobuf::Struct layout = ReadLayout(shot);
    EXPECT_NE(layout.fields().at("message").string_value().find(c.says), std::string::npos) << c.name;
    // The message is drawn in the frame area.
    EXPECT_GT(Luminance(ReadPng(shot), RegionOf(layout, "frame")).second, 5) << c.name;
  }
}

// No display: SDL would fall back to a driver that draws nowhere and the
// window would run unseen for ever; the viewer says why and exits 2.
TEST(Viewer, WithoutADisplayItExitsTwoAtOnce) {
  if (!fs::exists(kViewer)) GTEST_SKIP() << "cinevol-viewer was not built (libsdl2-dev, libimgui-dev)";
  ScratchDir scratch;
  const auto start = std::chrono::steady_clock::now();
  const auto [code, output] =
      RunProgram("/usr/bin/env",
                 {"-u", "DISPLAY", "-u", "WAYLAND_DISPLAY", "-u", "SDL_VIDEODRIVER", kViewer, "--server",
                  "127.0.0.1:" + std::to_string(FreePort()), "--connect-timeout", "1"},
                 scratch.path() / "viewer.log", std::chrono::seconds(30));
  EXPECT_EQ(code, 2) << output;
  EXPECT_NE(output.find("no display"), std::string::npos) << output;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
}

// Clipping and label events in a script go through the viewer's state as
// the panels would: the scene it saves afterwards holds them.
TEST(Viewer, ScriptedClippingAndLabelsShowInItsPanels) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  WriteSmallNrrd(scratch.path() / "small.nrrd");  // its values, 0 to 1500 by hundreds, serve as labels
  const fs::path saved = scratch.path() / "saved.json";
  const fs::path script = WriteScript(
      scratch.path() / "cut.jsonl",
      fmt::format(
          R"({{"session": {{"upload": "small.nrrd", "labels": {{"upload": "small.nrrd"}}, "stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "clipping": {{"cropBox": {{"center": {{"x": 2}}, "size": {{"x": 8, "y": 16, "z": 16}}}}, "planes": [{{"point": {{"z": 8}}, "normal": {{"z": 1}}, "cap": true}}]}}}}
{{"at": 0, "labels": {{"showUnlisted": false, "styles": [{{"value": 300, "visible": true}}]}}}}
{{"at": 0.1, "ui": {{"settle": true}}}}
{{"at": 0.1, "ui": {{"saveScene": "{}"}}}}
)",
          saved.string()));
  const ViewerRun run = RunViewer(scratch.path(), {"--server", server.address(), "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const v1::Scene scene = LoadSceneFile(saved);
  ASSERT_TRUE(scene.clipping().has_crop_box()) << "the crop box is not in the panel";
  EXPECT_FLOAT_EQ(scene.clipping().crop_box().size().x(), 8);
  ASSERT_EQ(scene.clipping().planes_size(), 1) << "the clip plane is not in the panel";
  EXPECT_TRUE(scene.clipping().planes(0).cap());
  ASSERT_EQ(scene.labels().styles_size(), 1) << "the label styles are not in the panel";
  EXPECT_EQ(scene.labels().styles(0).value(), 300u);
  EXPECT_FALSE(scene.labels().show_unlisted());
}

// Issue 56, bug 1: the viewer expanded presets itself, for a 1 mm voxel (ten
// times too dense on a 0.1 mm micro-CT). Now it sends the preset's name and
// shows the server's points: what it saves is what a session the server
// starts with that preset on the same volume holds, and the scene file reads back.
TEST(Viewer, APresetIsTheServersFitToTheVolumeNotTheViewers) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  const std::string micro_ct = "phantom:sphere?size=48&spacing=0.1";
  ServerProcess server(scratch.path(), {"--volume", micro_ct});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  v1::CreateSessionRequest reference;
  reference.set_volume_id(micro_ct);
  reference.set_preset("ct-bone");
  reference.mutable_viewport()->set_width(64);
  reference.mutable_viewport()->set_height(48);
  const v1::CreateSessionResponse fitted = client.CreateSession(reference);
  client.CloseSession(fitted.session_id());
  const v1::TransferFunction& want = fitted.scene().transfer_function();
  ASSERT_GT(want.points_size(), 1) << "the server did not expand the preset";
  const fs::path saved = scratch.path() / "saved.json";
  const fs::path script = WriteScript(scratch.path() / "preset.jsonl", fmt::format(R"({{"session": {{"preset": "ct-soft-tissue", "stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"preset": "ct-bone"}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"saveScene": "{}"}}}}
)",
                                                                                  saved.string()));
  const ViewerRun run =
      RunViewer(scratch.path(), {"--server", server.address(), "--volume", micro_ct, "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const v1::Scene scene = LoadSceneFile(saved);
  EXPECT_EQ(scene.frame(), v1::PATIENT_LPS);
  const v1::TransferFunction& got = scene.transfer_function();
  EXPECT_EQ(got.preset(), "ct-bone");
  ASSERT_EQ(got.points_size(), want.points_size()) << got.DebugString() << want.DebugString();
  for (int i = 0; i < want.points_size(); ++i) {
    EXPECT_NEAR(got.points(i).value(), want.points(i).value(), 1e-3) << "point " << i;
    EXPECT_NEAR(got.points(i).opacity(), want.points(i).opacity(), 1e-6) << "point " << i;
  }
  EXPECT_NEAR(got.density_scale(), want.density_scale(), 1e-6 * std::max(1.0f, want.density_scale()))
      << "the density is the server's fit to 0.1 mm voxels";
}

// Frame `n` of `movie`, decoded by ffmpeg into `png`.
ImageRgb8 MovieFrame(const fs::path& movie, int n, const fs::path& png) {
  const CommandResult decoded = RunCommand(fmt::format(
      "ffmpeg -v error -y -i '{}' -vf 'select=eq(n\\,{})' -frames:v 1 '{}'", movie.string(), n, png.string()));
  EXPECT_EQ(decoded.status, 0) << decoded.output;
  return ReadPng(png);
}

// The mean column of a bright sphere's pixels over a grey background: where
// it is across the picture, steady under the path tracer's noise (which
// alone changes a few samples a pixel by more than a voxel's move does).
double BrightColumn(const ImageRgb8& img, Region r) {
  double sum = 0, n = 0;
  for (int y = r.y; y < r.y + r.h && y < img.height; ++y) {
    for (int x = r.x; x < r.x + r.w && x < img.width; ++x) {
      const std::uint8_t* p = &img.bytes[(std::size_t(y) * img.width + x) * 3];
      if (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2] > 160) sum += x, ++n;
    }
  }
  EXPECT_GT(n, 100) << "no sphere in the picture";
  return sum / std::max(1.0, n);
}

// Issue 59: a time series in the viewer, scripted as a person would use the
// Time panel and the Scene panel's movie path. A script's time line sets the
// phase (the one event rule: as the panel's slider sends it); the frames then
// show that phase (the layout file says which), the sphere three voxels along.
// The movie's "phases" path records the loop from that phase in the series'
// own time: 0.1 s a phase at 25 frames/s, frame k shows phase 3 + floor(0.4 k)
// mod 5: frame 3 phase 4 (a voxel one way), frame 6 phase 0 (three the other),
// frame 13 phase 3 again.
TEST(Viewer, ATimeSeriesGoesToThePhaseSetAndRecordsItsLoop) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  WriteMovingSphere(scratch / "beat.nii", {});  // five phases, the sphere a voxel along each
  ServerProcess server(scratch.path(), {"--volume", (scratch / "beat.nii").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path first = scratch / "first.png", third = scratch / "third.png", movie = scratch / "beat.mp4";
  const fs::path script = WriteScript(
      scratch / "beat.jsonl", fmt::format(R"({{"session": {{"preset": "ct-bone", "stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"panel": {{"name": "stats", "open": false}}}}}}
{{"at": 0, "ui": {{"panel": {{"name": "time", "open": true}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.1, "time": {{"phase": 3}}}}
{{"at": 0.2, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.2, "ui": {{"movie": {{"file": "{}", "seconds": 0.6, "spp": 4, "phases": true}}}}}}
)",
                                          first.string(), third.string(), movie.string()));
  const ViewerRun run =
      RunViewer(scratch.path(), {"--server", server.address(), "--volume", "beat", "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;

  const google::protobuf::Struct before = ReadLayout(first), after = ReadLayout(third);
  EXPECT_EQ(before.fields().at("phase").number_value(), 0);
  EXPECT_EQ(after.fields().at("phase").number_value(), 3) << "the frame after the time line is not of phase 3";
  const Region frame = RegionOf(before, "frame");
  EXPECT_GT(std::abs(BrightColumn(ReadPng(third), frame) - BrightColumn(ReadPng(first), frame)), 20)
      << "three phases on, the sphere did not move across the view";

  const CommandResult probed = RunCommand(
      "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
      "stream=nb_read_frames -of default=nw=1 '" +
      movie.string() + "'");
  ASSERT_NE(probed.output.find("nb_read_frames=15"), std::string::npos) << probed.output << run.output;
  auto column = [&](int n) {
    const ImageRgb8 img = MovieFrame(movie, n, scratch / fmt::format("{}.png", n));
    return BrightColumn(img, {0, 0, img.width, img.height});
  };
  const double phase3 = column(0), phase4 = column(3), phase0 = column(6), again = column(13);
  EXPECT_LT((phase4 - phase3) * (phase0 - phase3), 0) << "phases 4 and 0 lie on opposite sides of phase 3";
  EXPECT_GT(std::abs(phase0 - phase3), 2 * std::abs(phase4 - phase3)) << "three voxels, then one";
  EXPECT_LT(std::abs(again - phase3), 0.1 * std::abs(phase0 - phase3))
      << "after one beat the loop is not back at phase 3";
}

// Pixels where green stands well above red and blue: the middle of the
// rainbow map, which the hot map (black, red, yellow, white) never draws.
int GreenPixels(const ImageRgb8& img, Region r) {
  int n = 0;
  for (int y = r.y; y < r.y + r.h && y < img.height; ++y) {
    for (int x = r.x; x < r.x + r.w && x < img.width; ++x) {
      const std::uint8_t* p = &img.bytes[(std::size_t(y) * img.width + x) * 3];
      n += p[1] > p[0] + 40 && p[1] > p[2] + 40;
    }
  }
  return n;
}

// Issue 59: a second volume in the viewer, started with --fuse on a server
// holding both (the head phantom and a sphere over it on a coarser grid;
// neither names a frame of reference, hence --align-by-patient). The session
// starts as the page's fuse= does: HOT at half opacity, the sphere glowing.
// The Second volume panel's controls, scripted ("secondVolume": the panel's
// edit through the shown session), turn the overlay to the rainbow map at
// 0.9 over a window that puts the sphere's 1000 in its middle and stop the
// glow: the server's scene has them (the scene saved after the settle), and
// the axial slice, which the server draws, turns green where the sphere is;
// the 3D view, without the glow, changes.
TEST(Viewer, TheSecondVolumePanelChangesTheFusedOverlayOnTheServer) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  constexpr const char* kHead = "phantom:head?size=48";
  constexpr const char* kSphere = "phantom:sphere?size=24&spacing=2";
  ServerProcess server(scratch.path(), {"--volume", kHead, "--volume", kSphere});
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path start = scratch / "start.png", edited = scratch / "edited.png", start_scene = scratch / "start.json",
                 edited_scene = scratch / "edited.json";
  const fs::path script =
      WriteScript(scratch / "fused.jsonl",
                  fmt::format(R"({{"session": {{"stream": {{"targetSpp": 4}}}}}}
{{"at": 0, "ui": {{"panel": {{"name": "stats", "open": false}}}}}}
{{"at": 0, "ui": {{"panel": {{"name": "secondVolume", "open": true}}}}}}
{{"at": 0, "ui": {{"layout2x2": true}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 0, "ui": {{"saveScene": "{}"}}}}
{{"at": 0.1, "ui": {{"secondVolume": {{"colorMap": "rainbow", "opacity": 0.9, "window": 2000, "level": 1000, "glow": false}}}}}}
{{"at": 0.2, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.2, "ui": {{"saveScene": "{}"}}}}
)",
                              start.string(), start_scene.string(), edited.string(), edited_scene.string()));
  const ViewerRun run = RunViewer(scratch.path(), {"--server", server.address(), "--volume", kHead, "--fuse", kSphere,
                                                   "--align-by-patient", "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;

  const v1::Fusion began = LoadSceneFile(start_scene).fusion();
  EXPECT_EQ(began.volume_id(), kSphere);
  EXPECT_TRUE(began.align_by_patient());
  EXPECT_EQ(began.overlay().color_map(), v1::HOT);
  EXPECT_FLOAT_EQ(began.overlay().opacity(), 0.5f);
  ASSERT_EQ(began.transfer_function().points_size(), 2) << "the sphere glows at first";
  EXPECT_FLOAT_EQ(began.transfer_function().points(1).emission().r(), 6);
  const v1::Fusion now = LoadSceneFile(edited_scene).fusion();
  EXPECT_EQ(now.volume_id(), kSphere);
  EXPECT_EQ(now.overlay().color_map(), v1::RAINBOW);
  EXPECT_FLOAT_EQ(now.overlay().opacity(), 0.9f);
  EXPECT_FLOAT_EQ(now.overlay().window(), 2000);
  EXPECT_FLOAT_EQ(now.overlay().level(), 1000);
  EXPECT_EQ(now.transfer_function().points_size(), 0) << "the glow was turned off";

  // The 3D view took the top-left quadrant; the axial slice is beside it.
  const Region frame = RegionOf(ReadLayout(edited), "frame");
  const Region axial{frame.x + frame.w, frame.y, frame.w, frame.h};
  EXPECT_EQ(GreenPixels(ReadPng(start), axial), 0) << "the hot map drew green";
  EXPECT_GT(GreenPixels(ReadPng(edited), axial), 200)
      << "the axial slice does not show the sphere through the rainbow map";
  EXPECT_GT(MeanDifference(ReadPng(start), ReadPng(edited), frame), 10) << "without its glow the 3D view is the same";
}

// A view key sends the view with the camera's eye and target: the server
// turns the camera about the same target at the same distance, and what the
// viewer shows (and saves) is the server's numbers. The script's next line
// waits for them.
TEST(Viewer, AViewKeyTurnsAboutTheSameTargetAtTheSameDistance) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path before = scratch.path() / "before.json", after = scratch.path() / "after.json";
  const fs::path script = WriteScript(scratch.path() / "view.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"drag": {{"button": "middle", "dx": 30, "dy": 10}}}}}}
{{"at": 0, "ui": {{"wheel": 2}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"saveScene": "{}"}}}}
{{"at": 0, "ui": {{"key": "l"}}}}
{{"at": 0, "ui": {{"saveScene": "{}"}}}}
)",
                                                                              before.string(), after.string()));
  const ViewerRun run = RunViewer(scratch.path(), {"--server", server.address(), "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  // Both in patient coordinates: distances and the left are the patient's.
  const v1::Camera a = LoadSceneFile(before).camera(), b = LoadSceneFile(after).camera();
  const auto vec = [](const v1::Vec3& v) { return Vec3f{v.x(), v.y(), v.z()}; };
  EXPECT_LT(Length(vec(b.target()) - vec(a.target())), 1e-2f) << "the target moved";
  const float distance = Length(vec(a.eye()) - vec(a.target()));
  EXPECT_NEAR(Length(vec(b.eye()) - vec(b.target())), distance, 1e-2f) << "the distance changed";
  const Vec3f to_eye = Normalize(vec(b.eye()) - vec(b.target()));
  EXPECT_GT(to_eye.x, 0.999f) << "the eye is not on the patient's left";
  EXPECT_EQ(b.view(), v1::NAMED_VIEW_UNSPECIFIED) << "the file holds the numbers";
}

// The Struct a script run printed for a PACS action: every "cinevol-viewer: ACTION {...}" line of `output`.
std::vector<google::protobuf::Struct> Reported(const std::string& output, const std::string& action) {
  std::vector<google::protobuf::Struct> lines;
  const std::string prefix = "cinevol-viewer: " + action + " {";
  for (std::size_t at = output.find(prefix); at != std::string::npos; at = output.find(prefix, at + 1)) {
    const std::size_t json = at + prefix.size() - 1;
    google::protobuf::Struct line;
    const std::string text = output.substr(json, output.find('\n', json) - json);
    EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(text, &line).ok()) << text;
    lines.push_back(line);
  }
  return lines;
}

std::string TextField(const google::protobuf::Struct& s, const std::string& key) {
  const auto it = s.fields().find(key);
  return it == s.fields().end() ? "" : it->second.string_value();
}

// The volume source of a session the server holds for us, where one renders a series from a PACS.
std::string PacsSessionSource(Client& client) {
  const v1::ServerStatus status = client.Status();
  for (const v1::SessionStatus& session : status.sessions()) {
    const std::string source = client.DescribeVolume(session.volume_id()).source();
    if (source.rfind("pacs:orthanc/", 0) == 0) return source;
  }
  return {};
}

// A real Orthanc (tests/pacs/orthanc_process.h) holding the shared JPEG 2000
// CT stamped as `ct`, and a server that names it "orthanc" with its
// credentials. `why` says what did not start.
struct PacsWithCt {
  PacsWithCt(const fs::path& scratch, const SeriesStamp& ct) {
    fs::create_directories(scratch / "orthanc");
    orthanc = std::make_unique<OrthancProcess>(scratch / "orthanc");
    if (!orthanc->running()) {
      why = orthanc->Log();
      return;
    }
    const auto files = DicomFilesIn(SharedData() / "ct-body-totalsegmentator/example_ct_dicom");
    for (const StampedInstance& instance : StampSeries(files, ct, scratch / "stamped").instances) {
      if (orthanc->Upload(instance.bytes) != 200) {
        why = "Orthanc refused an upload";
        return;
      }
    }
    const pacs::PacsConfig pacs = orthanc->Pacs();
    const fs::path credentials = scratch / "pacs-credentials";
    std::ofstream(credentials) << "orthanc basic " << pacs.credentials.user << ":" << pacs.credentials.password << "\n";
    server = std::make_unique<ServerProcess>(scratch, std::vector<std::string>{"--pacs", "orthanc=" + pacs.base_url,
                                                                              "--pacs-credentials", credentials.string(),
                                                                              "--pacs-timeout-seconds", "10"});
    if (!server->running()) why = server->Log();
  }
  bool ready() const { return server && server->running(); }

  std::unique_ptr<OrthancProcess> orthanc;
  std::unique_ptr<ServerProcess> server;
  std::string why;
};

// The PACS panel against a real Orthanc (tests/pacs/orthanc_process.h) holding the shared JPEG 2000 CT, stamped:
// a script searches a PACS the server does not name (an error), then by patient ID, lists the study's series and
// opens one. The viewer prints what it found (UIDs, no patient fields), and its session moves to the series.
TEST(Viewer, APacsSeriesIsFoundListedAndOpenedFromItsPanel) {
  CINEVOL_REQUIRE_VIEWER();
  if (const std::string missing = OrthancProcess::WhatIsMissing(); !missing.empty()) GTEST_SKIP() << missing;
  CINEVOL_REQUIRE_SHARED_DATA();
  const SeriesStamp ct{"2.25.3410201", "2.25.3410201.1", "CINEVOL-VIEWER-CT", "Cinevol^Viewer"};
  ScratchDir scratch;
  const PacsWithCt stack(scratch.path(), ct);
  ASSERT_TRUE(stack.ready()) << stack.why;
  const ServerProcess& server = *stack.server;

  const fs::path shot = scratch.path() / "opened.png";
  // Each action waits for the one before (settle); the last line keeps the session a while for the checks below.
  const fs::path script = WriteScript(scratch.path() / "pacs.jsonl",
                                      fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"searchPacs": {{"pacs": "nope"}}}}}}
{{"at": 0, "ui": {{"searchPacs": {{"pacs": "orthanc", "patientId": "{0}", "modality": "CT"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"selectStudy": {{"pacs": "orthanc", "studyUid": "{1}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"openSeries": {{"pacs": "orthanc", "studyUid": "{1}", "seriesUid": "{2}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{3}"}}}}
{{"at": 4, "ui": {{"settle": true}}}}
)",
                                                  ct.patient_id, ct.study_uid, ct.series_uid, shot.string()));
  const auto args = XvfbRunArgs({"--server", server.address(), "--script", script.string(), "--max-seconds", "80"});
  const pid_t viewer = Spawn("/usr/bin/xvfb-run", args, scratch.path() / "viewer.log");
  ASSERT_GT(viewer, 0);
  // While the script runs, the server renders the series from the PACS for the viewer.
  Client client = server.Connect();
  std::string source;
  int status = -1;
  for (int i = 0; i < 1000 && source.empty() && status == -1; ++i) {
    source = PacsSessionSource(client);
    status = WaitExit(viewer, std::chrono::milliseconds(100));
  }
  if (status == -1) status = WaitExit(viewer, std::chrono::seconds(100));
  std::ifstream log(scratch.path() / "viewer.log");
  const std::string output{std::istreambuf_iterator<char>(log), {}};
  ASSERT_TRUE(status != -1 && WIFEXITED(status)) << output;
  EXPECT_EQ(ViewerExitCode(output, WEXITSTATUS(status)), 0) << output;
  EXPECT_EQ(source, fmt::format("pacs:orthanc/{}/{}", ct.study_uid, ct.series_uid)) << "no session on the series";

  const auto searches = Reported(output, "searchPacs");
  ASSERT_EQ(searches.size(), 2u) << output;
  EXPECT_EQ(TextField(searches[0], "error"), "INVALID_ARGUMENT") << output;
  const auto& studies = searches[1].fields().at("studyUids").list_value().values();
  ASSERT_EQ(studies.size(), 1) << output;
  EXPECT_EQ(studies[0].string_value(), ct.study_uid);
  const auto listed = Reported(output, "selectStudy");
  ASSERT_EQ(listed.size(), 1u) << output;
  const auto& series = listed[0].fields().at("series").list_value().values();
  ASSERT_EQ(series.size(), 1) << output;
  EXPECT_EQ(TextField(series[0].struct_value(), "seriesUid"), ct.series_uid);
  EXPECT_EQ(series[0].struct_value().fields().at("instances").number_value(), 20);
  const auto opened = Reported(output, "openSeries");
  ASSERT_EQ(opened.size(), 1u) << output;
  EXPECT_EQ(TextField(opened[0], "source"), source);
  // The screenshot after the open shows the new session's frame.
  const google::protobuf::Struct layout = ReadLayout(shot);
  EXPECT_EQ(layout.fields().at("state").number_value(), 1) << TextField(layout, "message");
  EXPECT_EQ(TextField(layout, "message").rfind(TextField(opened[0], "volumeId") + " on ", 0), 0u)
      << TextField(layout, "message");
  EXPECT_GT(layout.fields().at("frameId").number_value(), 0);
  // Patient fields went to the panel only.
  EXPECT_EQ(output.find(ct.patient_id), std::string::npos) << output;
  EXPECT_EQ(output.find(ct.patient_name), std::string::npos) << output;
}

// Measurements to the PACS and back (issue 57): a distance measured on a
// series from a real Orthanc is stored from the panel as an SR; a second
// viewer opens the series, then the report from the study's series list,
// and shows the same measurement (points within 0.01 mm).
TEST(Viewer, MeasurementsGoToThePacsAsAReportAndComeBack) {
  CINEVOL_REQUIRE_VIEWER();
  if (const std::string missing = OrthancProcess::WhatIsMissing(); !missing.empty()) GTEST_SKIP() << missing;
  CINEVOL_REQUIRE_SHARED_DATA();
  const SeriesStamp ct{"2.25.3410301", "2.25.3410301.1", "CINEVOL-VIEWER-SR", "Cinevol^Report"};
  ScratchDir scratch;
  const PacsWithCt stack(scratch.path(), ct);
  ASSERT_TRUE(stack.ready()) << stack.why;
  const ServerProcess& server = *stack.server;
  const std::string open_images = fmt::format(
      R"({{"at": 0, "ui": {{"openSeries": {{"pacs": "orthanc", "studyUid": "{}", "seriesUid": "{}"}}}}}})",
      ct.study_uid, ct.series_uid);

  const fs::path measured = scratch.path() / "measured.json";
  const fs::path store = WriteScript(scratch.path() / "store.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"layout2x2": true}}}}
{{"at": 0.1, "ui": {{"settle": true}}}}
{{"at": 0.1, "ui": {{"measureDistance": true}}}}
{{"at": 0.1, "ui": {{"pickAt": {{"x": 0.5, "y": 0.5}}}}}}
{{"at": 0.2, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"clickSlice": {{"pane": "axial", "x": 0.3, "y": 0.5}}}}}}
{{"at": 0.3, "ui": {{"settle": true}}}}
{{"at": 0.3, "ui": {{"storeMeasurements": {{"pacs": "orthanc"}}}}}}
{{"at": 0.3, "ui": {{"settle": true}}}}
{{"at": 0.3, "ui": {{"saveScene": "{}"}}}}
)",
                                                                                    open_images, measured.string()));
  const ViewerRun stored = RunViewer(scratch.path(), {"--server", server.address(), "--script", store.string()});
  ASSERT_EQ(stored.exit_code, 0) << stored.output;
  const auto reports = Reported(stored.output, "storeMeasurements");
  ASSERT_EQ(reports.size(), 1u) << stored.output;
  const std::string report_series = TextField(reports[0], "seriesUid");
  const v1::Scene before = LoadSceneFile(measured);
  ASSERT_EQ(before.measurements_size(), 1) << stored.output;

  const fs::path restored = scratch.path() / "restored.json";
  const fs::path load = WriteScript(scratch.path() / "load.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"selectStudy": {{"pacs": "orthanc", "studyUid": "{}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"openSeries": {{"pacs": "orthanc", "studyUid": "{}", "seriesUid": "{}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"saveScene": "{}"}}}}
)",
                                                                                  open_images, ct.study_uid, ct.study_uid,
                                                                                  report_series, restored.string()));
  const ViewerRun loaded = RunViewer(scratch.path(), {"--server", server.address(), "--script", load.string()});
  ASSERT_EQ(loaded.exit_code, 0) << loaded.output;
  EXPECT_EQ(Reported(loaded.output, "openSeries").size(), 1u) << "the report opened as a volume: " << loaded.output;
  const v1::Scene after = LoadSceneFile(restored);
  ASSERT_EQ(after.measurements_size(), 1) << loaded.output;
  ASSERT_EQ(after.measurements(0).points_size(), 2);
  for (int i = 0; i < 2; ++i) {
    const v1::Vec3 &a = before.measurements(0).points(i), &b = after.measurements(0).points(i);
    EXPECT_NEAR(a.x(), b.x(), 0.01);
    EXPECT_NEAR(a.y(), b.y(), 0.01);
    EXPECT_NEAR(a.z(), b.z(), 0.01);
  }
}

// A still's presentation state opened from the study's series list (issue 57): the viewer loads the series it
// presents and starts its session in the state's scene: the camera, the transfer function and the clip plane the
// still was stored with.
TEST(Viewer, APresentationStateOpensItsSeriesInItsScene) {
  CINEVOL_REQUIRE_VIEWER();
  if (const std::string missing = OrthancProcess::WhatIsMissing(); !missing.empty()) GTEST_SKIP() << missing;
  CINEVOL_REQUIRE_SHARED_DATA();
  const SeriesStamp ct{"2.25.3410401", "2.25.3410401.1", "CINEVOL-VIEWER-PR", "Cinevol^Presented"};
  ScratchDir scratch;
  const PacsWithCt stack(scratch.path(), ct);
  ASSERT_TRUE(stack.ready()) << stack.why;
  const ServerProcess& server = *stack.server;
  v1::LoadSeriesRequest series;
  series.set_pacs("orthanc");
  series.set_study_uid(ct.study_uid);
  series.set_series_uid(ct.series_uid);
  const v1::VolumeInfo volume = server.Connect().LoadSeries(series);
  const fs::path scene = scratch.path() / "stored.json";
  std::ofstream(scene) << R"({"frame": "PATIENT_LPS", "transferFunction": {"preset": "ct-bone"},
    "camera": {"eye": {"x": 40, "y": -700, "z": -785}, "target": {"x": 0, "y": -150, "z": -785}, "fovYDeg": 25},
    "clipping": {"planes": [{"point": {"x": 20, "y": 0, "z": 0}, "normal": {"x": -1, "y": 0, "z": 0}}]}})";
  const auto [code, out] = RunProgram(CliPath(),
                                      {"snapshot", "--server", server.address(), "--volume", volume.id(), "--scene",
                                       scene.string(), "--width", "64", "--height", "48", "--spp", "2", "--out",
                                       (scratch.path() / "still.png").string(), "--store-to", "orthanc"},
                                      scratch.path() / "cli.log", std::chrono::seconds(120));
  ASSERT_EQ(code, 0) << out;
  const std::size_t at = out.find("its presentation state: series ");
  ASSERT_NE(at, std::string::npos) << out;
  const std::string presentation_series = out.substr(at + 31, out.find(',', at) - at - 31);

  const fs::path opened = scratch.path() / "opened.json";
  const fs::path script = WriteScript(scratch.path() / "presentation.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"selectStudy": {{"pacs": "orthanc", "studyUid": "{0}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"openSeries": {{"pacs": "orthanc", "studyUid": "{0}", "seriesUid": "{1}"}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"saveScene": "{2}"}}}}
)",
                                                                                      ct.study_uid, presentation_series,
                                                                                      opened.string()));
  const ViewerRun run = RunViewer(scratch.path(), {"--server", server.address(), "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto reports = Reported(run.output, "openSeries");
  ASSERT_EQ(reports.size(), 1u) << run.output;
  EXPECT_EQ(TextField(reports[0], "seriesUid"), ct.series_uid) << "the series it presents, not the PR series";
  EXPECT_TRUE(reports[0].fields().at("presentation").bool_value());
  const v1::Scene shown = LoadSceneFile(opened);
  EXPECT_NEAR(shown.camera().eye().x(), 40, 0.01);
  EXPECT_NEAR(shown.camera().eye().y(), -700, 0.01);
  EXPECT_NEAR(shown.camera().target().y(), -150, 0.01);
  EXPECT_NEAR(shown.camera().fov_y_deg(), 25, 1e-3);
  EXPECT_EQ(shown.transfer_function().preset(), "ct-bone");
  ASSERT_EQ(shown.clipping().planes_size(), 1) << run.output;
  EXPECT_NEAR(shown.clipping().planes(0).point().x(), 20, 0.01);
}

// The reading tools driven as a reader would: the 2x2 layout fetches the
// three slices through the crosshair, a click on the 3D view picks, a click
// on a slice ends a distance measurement and moves the crosshair, and the
// saved scene keeps the measurement, which opening it brings back.
TEST(Viewer, PicksShowsSlicesInTwoByTwoAndMeasures) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path grid = scratch.path() / "grid.png", scene = scratch.path() / "measured.json",
                 deleted = scratch.path() / "deleted.json", reopened = scratch.path() / "reopened.json";
  const fs::path script =
      WriteScript(scratch.path() / "reading.jsonl",
                  fmt::format(R"({{"session": {{"stream": {{"targetSpp": 4}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"layout2x2": true}}}}
{{"at": 0.1, "ui": {{"settle": true}}}}
{{"at": 0.1, "ui": {{"measureDistance": true}}}}
{{"at": 0.1, "ui": {{"pickAt": {{"x": 0.5, "y": 0.5}}}}}}
{{"at": 0.2, "ui": {{"settle": true}}}}
{{"at": 0.2, "ui": {{"clickSlice": {{"pane": "axial", "x": 0.3, "y": 0.5}}}}}}
{{"at": 0.3, "ui": {{"settle": true}}}}
{{"at": 0.3, "ui": {{"saveScene": "{}"}}}}
{{"at": 0.3, "ui": {{"screenshot": "{}"}}}}
{{"at": 0.4, "ui": {{"deleteMeasurement": 0}}}}
{{"at": 0.4, "ui": {{"saveScene": "{}"}}}}
{{"at": 0.4, "ui": {{"openScene": "{}"}}}}
{{"at": 0.4, "ui": {{"saveScene": "{}"}}}}
)",
                              scene.string(), grid.string(), deleted.string(), scene.string(), reopened.string()));
  const ViewerRun run = RunViewer(scratch.path(), {"--server", server.address(), "--script", script.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;

  const auto picks = Reported(run.output, "pick");
  ASSERT_EQ(picks.size(), 1u) << run.output;
  EXPECT_TRUE(picks[0].fields().at("hit").bool_value()) << "the view's centre is on the head: " << run.output;
  EXPECT_NE(TextField(picks[0], "text").find(" mm, value "), std::string::npos) << TextField(picks[0], "text");
  std::set<std::string> axes;
  for (const auto& slice : Reported(run.output, "slice")) {
    axes.insert(TextField(slice, "axis"));
    EXPECT_EQ(TextField(slice, "letters").size(), 4u);
  }
  EXPECT_EQ(axes, (std::set<std::string>{"axial", "coronal", "sagittal"})) << run.output;
  // Three at the start, three through the pick, three through the click on the axial slice.
  EXPECT_EQ(Reported(run.output, "slice").size(), 9u) << run.output;
  const auto measured = Reported(run.output, "measurement");
  ASSERT_EQ(measured.size(), 1u) << run.output;
  EXPECT_NE(TextField(measured[0], "value").find(" mm"), std::string::npos);
  const v1::Scene saved = LoadSceneFile(scene);
  ASSERT_EQ(saved.measurements_size(), 1) << "the saved scene lost the measurement";
  EXPECT_EQ(saved.measurements(0).points_size(), 2);
  EXPECT_EQ(LoadSceneFile(deleted).measurements_size(), 0);
  EXPECT_EQ(LoadSceneFile(reopened).measurements_size(), 1) << "opening the scene did not restore the measurement";
  // The 3D view took the top-left quadrant; the axial slice beside it is an image, not the background.
  const google::protobuf::Struct layout = ReadLayout(grid);
  const Region frame = RegionOf(layout, "frame");
  const Region axial{frame.x + frame.w, frame.y, frame.w, frame.h};
  EXPECT_GT(Luminance(ReadPng(grid), axial).second, 10) << "the axial pane is blank";
}

// ------------------------------------------------------------ sharing

std::string ReadText(const fs::path& file) {
  std::ifstream in(file);
  return {std::istreambuf_iterator<char>(in), {}};
}

// A viewer run in the background, for tests that act while it runs.
class BackgroundViewer {
 public:
  BackgroundViewer(const fs::path& scratch, const std::vector<std::string>& args)
      : log_(scratch / "viewer.log"), pid_(Spawn("/usr/bin/xvfb-run", XvfbRunArgs(args), log_)) {}
  ~BackgroundViewer() {
    if (pid_ > 0 && status_ == -1) kill(pid_, SIGTERM);  // a failed test; the viewer's own timeout ends it too
  }
  bool started() const { return pid_ > 0; }
  // What it printed, up to its last whole line.
  std::string Output() const {
    const std::string text = ReadText(log_);
    return text.substr(0, text.rfind('\n') + 1);
  }
  // Whether it exited within `within`.
  bool Wait(std::chrono::milliseconds within) {
    if (status_ == -1) status_ = WaitExit(pid_, within);
    return status_ != -1;
  }
  int exit_code() const {
    return status_ != -1 && WIFEXITED(status_) ? ViewerExitCode(ReadText(log_), WEXITSTATUS(status_)) : -1;
  }
  // Its first "cinevol-viewer: ACTION {...}" line, waiting up to `within` while it runs.
  std::optional<google::protobuf::Struct> AwaitReport(const std::string& action, std::chrono::seconds within) {
    const auto end = std::chrono::steady_clock::now() + within;
    for (;;) {
      if (const auto lines = Reported(Output(), action); !lines.empty()) return lines.front();
      if (Wait(std::chrono::milliseconds(100)) || std::chrono::steady_clock::now() > end) return std::nullopt;
    }
  }

 private:
  fs::path log_;
  pid_t pid_;
  int status_ = -1;
};

// The watch's messages until one meets `want`; false once the call ended or `within` passed.
bool WatchUntil(SessionWatch& watch, const std::function<bool(const v1::ServerMessage&)>& want,
                std::chrono::seconds within) {
  const auto end = std::chrono::steady_clock::now() + within;
  while (std::chrono::steady_clock::now() < end) {
    const auto message = watch.Next(std::chrono::milliseconds(200));
    if (message && want(*message)) return true;
    if (!message && watch.ended()) return false;
  }
  return false;
}

std::function<bool(const v1::ServerMessage&)> PresenterIs(const std::string& who, bool is = true) {
  return [=](const v1::ServerMessage& m) { return m.has_state() && (m.state().presenter() == who) == is; };
}

v1::SessionEvent PointerEvent(float x, float y) {
  v1::SessionEvent e;
  e.mutable_pointer()->set_x(x);
  e.mutable_pointer()->set_y(y);
  return e;
}

// A session of the test's own, streaming, shared as a link viewer whose pointer is shown.
struct SharedSession {
  explicit SharedSession(ServerProcess& server) : owner(server.Connect()) {
    v1::CreateSessionRequest request = SmallSession("ct-bone", 96, 64);
    request.mutable_stream()->set_target_spp(4);
    created = owner.CreateSession(request);
    stream = owner.Attach(created.session_id());
    v1::ShareSessionRequest share;
    share.set_session_id(created.session_id());
    share.set_role(v1::VIEWER);
    share.set_allow_pointer(true);
    grant = owner.Share(share);
  }
  Client owner;
  v1::CreateSessionResponse created;
  std::unique_ptr<SessionStream> stream;
  v1::Grant grant;
};

// The owner's Share panel, scripted: it shares a link; a watcher holding the
// secret it reports (the client library, no token) gets frames and shows its
// pointer; the owner hands it the presenter's role, it drives, and the owner
// takes the role back. The viewer hears of each step.
TEST(Viewer, SharesALinkThatIsWatchedAndHandsThePresentersRoleOverAndBack) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  const fs::path presented = scratch.path() / "presented.png";
  const fs::path script =
      WriteScript(scratch.path() / "share.jsonl", fmt::format(R"({{"session": {{"stream": {{"targetSpp": 2}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"share": {{"link": true, "role": "viewer", "allowPointer": true}}}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 6, "ui": {{"handover": {{"grant": "last"}}}}}}
{{"at": 6, "ui": {{"settle": true}}}}
{{"at": 14, "ui": {{"screenshot": "{}"}}}}
{{"at": 14, "ui": {{"handover": {{"grant": ""}}}}}}
{{"at": 14, "ui": {{"settle": true}}}}
)",
                                                              presented.string()));
  BackgroundViewer viewer(scratch.path(), {"--server", server.address(), "--script", script.string()});
  ASSERT_TRUE(viewer.started());
  const auto shared = viewer.AwaitReport("share", std::chrono::seconds(60));
  ASSERT_TRUE(shared) << viewer.Output();
  const std::string id = TextField(*shared, "id"), secret = TextField(*shared, "secret"), link = "link " + id;
  ASSERT_EQ(secret.rfind("cvg_" + id + "_", 0), 0u) << secret;

  SessionWatch watch({grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials())}, secret, "");
  EXPECT_TRUE(WatchUntil(
      watch, [](const v1::ServerMessage& m) { return m.has_frame(); }, std::chrono::seconds(60)))
      << watch.status().error_message();
  EXPECT_NO_THROW(watch.Send({PointerEvent(0.25f, 0.75f)})) << "the link was shared with its pointer";
  v1::SessionEvent left;
  left.mutable_camera()->set_view(v1::LEFT);
  ExpectRpcError([&] { watch.Send({left}); }, grpc::StatusCode::PERMISSION_DENIED, "viewer's");
  ASSERT_TRUE(WatchUntil(watch, PresenterIs(link), std::chrono::seconds(60))) << "no hand-over: " << viewer.Output();
  EXPECT_NO_THROW(watch.Send({left})) << "the presenter drives";
  EXPECT_TRUE(WatchUntil(watch, PresenterIs(link, false), std::chrono::seconds(60)))
      << "the owner did not take it back";
  ExpectRpcError([&] { watch.Send({left}); }, grpc::StatusCode::PERMISSION_DENIED, "viewer's");
  watch.Cancel();
  ASSERT_TRUE(viewer.Wait(std::chrono::seconds(100))) << viewer.Output();
  const std::string output = viewer.Output();
  EXPECT_EQ(viewer.exit_code(), 0) << output;

  // It heard of its watcher, of the watcher's pointer and of the presenter it made.
  bool watched = false, pointed = false, presenting = false;
  for (const auto& line : Reported(output, "sharing")) {
    watched |= line.fields().at("viewers").number_value() == 1;
    for (const auto& who : line.fields().at("pointers").list_value().values()) pointed |= who.string_value() == link;
    presenting |= TextField(line, "banner") == link + " presents · 1 viewer (Share: Take back)";
  }
  EXPECT_TRUE(watched) << output;
  EXPECT_TRUE(pointed) << output;
  EXPECT_TRUE(presenting) << output;
  const auto handovers = Reported(output, "handover");
  ASSERT_EQ(handovers.size(), 2u) << output;
  EXPECT_EQ(TextField(handovers[0], "presenter"), link);
  EXPECT_EQ(TextField(handovers[1], "presenter"), "anonymous");
  const google::protobuf::Struct layout = ReadLayout(presented);
  EXPECT_EQ(layout.fields().at("state").number_value(), 1) << TextField(layout, "message");
  EXPECT_GT(layout.fields().at("frameId").number_value(), 0);
}

// A viewer started with --grant watches a session the test made and shared:
// its frames at the session's size under "Watching <owner>"; its pointer
// reaches the owner; its drag, wheel, key and preset change nothing there.
TEST(Viewer, WatchesASharedSessionByItsGrantAndCannotDriveIt) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  SharedSession session(server);
  ASSERT_TRUE(WaitFinal(*session.stream)) << session.stream->status().error_message();
  const v1::SessionState before = session.stream->state().value_or(v1::SessionState{});
  const std::string link = "link " + session.grant.id();
  const fs::path shot = scratch.path() / "watching.png";
  const fs::path script = WriteScript(scratch.path() / "watch.jsonl", fmt::format(R"({{"session": {{}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"drag": {{"button": "left", "dx": 150, "dy": 40}}}}}}
{{"at": 0, "ui": {{"wheel": 3}}}}
{{"at": 0, "ui": {{"key": "l"}}}}
{{"at": 0, "ui": {{"preset": "ct-soft-tissue"}}}}
{{"at": 0, "ui": {{"pointer": {{"x": 0.25, "y": 0.75}}}}}}
{{"at": 1, "ui": {{"settle": true}}}}
{{"at": 1, "ui": {{"screenshot": "{}"}}}}
)",
                                                                                  shot.string()));
  BackgroundViewer viewer(scratch.path(), {"--server", server.address(), "--grant", session.grant.secret(), "--script",
                                           script.string(), "--max-seconds", "40"});
  ASSERT_TRUE(viewer.started());
  // Meanwhile the owner reads its stream: the states say what the session is and who points.
  std::optional<v1::SharedPointer> pointer;
  auto read_states = [&] {
    while (const auto m = session.stream->Next(std::chrono::milliseconds(0))) {
      if (!m->has_state()) continue;
      for (const v1::SharedPointer& p : m->state().pointers()) {
        if (p.who() == link) pointer = p;
      }
    }
  };
  while (!viewer.Wait(std::chrono::milliseconds(50))) read_states();
  read_states();
  const std::string output = viewer.Output();
  EXPECT_EQ(viewer.exit_code(), 0) << output;

  const auto lines = Reported(output, "sharing");
  ASSERT_FALSE(lines.empty()) << output;
  EXPECT_EQ(TextField(lines.back(), "presenter"), "anonymous") << output;
  EXPECT_EQ(TextField(lines.back(), "banner"), "Watching anonymous · 1 viewer") << output;
  EXPECT_FALSE(lines.back().fields().at("drives").bool_value()) << output;
  ASSERT_TRUE(pointer) << "the viewer's pointer did not reach the owner: " << output;
  EXPECT_FLOAT_EQ(pointer->x(), 0.25f);
  EXPECT_FLOAT_EQ(pointer->y(), 0.75f);
  const v1::SessionState after = session.stream->state().value_or(v1::SessionState{});
  EXPECT_EQ(after.last_event_seq(), before.last_event_seq()) << "an event of the viewer's was applied";
  EXPECT_EQ(after.scene().camera().DebugString(), before.scene().camera().DebugString());
  EXPECT_EQ(after.scene().transfer_function().DebugString(), before.scene().transfer_function().DebugString());
  EXPECT_EQ(output.find(session.grant.secret()), std::string::npos) << "the secret is never printed";
  // Its screenshot: the session's frame at the session's own size, fitted into the view.
  const google::protobuf::Struct layout = ReadLayout(shot);
  EXPECT_EQ(layout.fields().at("state").number_value(), 1) << TextField(layout, "message");
  EXPECT_GT(layout.fields().at("frameId").number_value(), 0);
  const auto& size = layout.fields().at("frameSize").list_value().values();
  EXPECT_EQ(size[0].number_value(), 96);
  EXPECT_EQ(size[1].number_value(), 64);
  EXPECT_GT(Luminance(ReadPng(shot), RegionOf(layout, "frame")).second, 10) << "no frame shown";
}

// Revoking the grant ends the watching viewer at once, with the server's
// words in its banner and on stderr (exit 3).
TEST(Viewer, ARevokedGrantEndsTheWatchWithTheServersWords) {
  CINEVOL_REQUIRE_VIEWER();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  SharedSession session(server);
  const fs::path watching = scratch.path() / "watching.png", last = scratch.path() / "last.png";
  const fs::path script = WriteScript(scratch.path() / "revoked.jsonl", fmt::format(R"({{"session": {{}}}}
{{"at": 0, "ui": {{"settle": true}}}}
{{"at": 0, "ui": {{"screenshot": "{}"}}}}
{{"at": 60, "ui": {{"quit": true}}}}
)",
                                                                                    watching.string()));
  BackgroundViewer viewer(scratch.path(), {"--server", server.address(), "--grant", session.grant.secret(), "--script",
                                           script.string(), "--screenshot", last.string()});
  ASSERT_TRUE(viewer.started());
  const fs::path shown = fs::path(watching).replace_extension(".layout.json");
  for (int i = 0; i < 600 && !fs::exists(shown) && !viewer.Wait(std::chrono::milliseconds(100)); ++i) {
  }
  ASSERT_TRUE(fs::exists(shown)) << "it never showed the session: " << viewer.Output();
  const auto revoked = std::chrono::steady_clock::now();
  EXPECT_EQ(session.owner.RevokeShare(session.created.session_id(), session.grant.id()), 1u);
  ASSERT_TRUE(viewer.Wait(std::chrono::seconds(60))) << viewer.Output();
  EXPECT_LT(std::chrono::steady_clock::now() - revoked, std::chrono::seconds(20)) << "it did not end at once";
  const std::string output = viewer.Output(), said = fmt::format("grant {} was revoked", session.grant.id());
  EXPECT_EQ(viewer.exit_code(), 3) << output;
  EXPECT_NE(output.find(said), std::string::npos) << output;
  const google::protobuf::Struct layout = ReadLayout(last);
  EXPECT_EQ(layout.fields().at("state").number_value(), 3) << TextField(layout, "message");
  EXPECT_NE(TextField(layout, "message").find(said), std::string::npos) << TextField(layout, "message");
  EXPECT_GT(Luminance(ReadPng(last), RegionOf(layout, "frame")).second, 5) << "no banner drawn";
}

}  // namespace
}  // namespace cinevol::testing

// `cinevol movie` (issue 58): a session's refined stills along an orbit or a sweep, rendered and encoded by the
// server's RenderMovie as H.264 in an MP4 that FFmpeg's own tools read back with the frame count, size and profile
// asked for; the frames move as the path says; what cannot be a movie is refused before a still is rendered.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>

#include "encode/image_codecs.h"
#include "service/server_process.h"
#include "support/shell_command.h"
#include "support/test_paths.h"
#include "support/time_series_nifti.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// ffprobe's count of the decoded frames and what the stream says of itself.
std::string Probe(const fs::path& movie) {
  return RunCommand(
             "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
             "stream=codec_name,profile,width,height,nb_read_frames,avg_frame_rate -of default=nw=1 '" +
             movie.string() + "'")
      .output;
}

// Frame `n` of `movie`, decoded by ffmpeg.
ImageRgb8 Frame(const fs::path& movie, int n, const fs::path& png) {
  const CommandResult decoded = RunCommand(fmt::format(
      "ffmpeg -v error -y -i '{}' -vf 'select=eq(n\\,{})' -frames:v 1 '{}'", movie.string(), n, png.string()));
  EXPECT_EQ(decoded.status, 0) << decoded.output;
  std::ifstream in(png, std::ios::binary);
  return DecodePng(std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {}));
}

double MeanDifference(const ImageRgb8& a, const ImageRgb8& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.bytes.size(); ++i) sum += std::abs(int(a.bytes[i]) - int(b.bytes[i]));
  return sum / double(a.bytes.size());
}

constexpr const char* kHead = "phantom:head?size=48";

class MovieCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(Installed("ffprobe") && Installed("ffmpeg")) << "FFmpeg is not installed: run scripts/install-deps.sh";
    // The head, and a time series: a sphere that moves a voxel a phase, 0.1 s apart.
    WriteMovingSphere(scratch_ / "beat.nii", {});
    server_ = std::make_unique<ServerProcess>(
        scratch_.path(), std::vector<std::string>{"--volume", kHead, "--volume", (scratch_ / "beat.nii").string()});
    ASSERT_TRUE(server_->running()) << server_->Log();
  }

  std::pair<int, std::string> Movie(std::vector<std::string> args) {
    args.insert(args.begin(), "movie");
    args.insert(args.end(), {"--server", server_->address()});
    return RunProgram(CliPath(), args, scratch_ / "movie.log", 120s);
  }

  ScratchDir scratch_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(MovieCommand, AnOrbitIsAnH264Mp4OfItsFramesWhichTurn) {
  const fs::path out = scratch_ / "orbit.mp4";
  const auto [code, said] = Movie({"--volume", kHead, "--orbit", "360", "--seconds", "1.2", "--fps", "10", "--width",
                                   "96", "--height", "64", "--spp", "4", "--out", out.string()});
  ASSERT_EQ(code, 0) << said;
  EXPECT_TRUE(Has(said, "movie: frame 0/12, 4 spp each")) << said;  // progress as soon as the server takes it
  EXPECT_TRUE(Has(said, "wrote " + out.string() + ": 12 frames of 96x64 at 10 frames/s")) << said;
  const std::string probed = Probe(out);
  for (const char* expected :
       {"codec_name=h264", "profile=High", "width=96", "height=64", "nb_read_frames=12", "avg_frame_rate=10/1"}) {
    EXPECT_TRUE(Has(probed, expected)) << expected << "\n" << probed;
  }
  // A quarter turn apart the head looks different; the loop's last frame is a step short of the first.
  const ImageRgb8 first = Frame(out, 0, scratch_ / "0.png"), quarter = Frame(out, 3, scratch_ / "3.png");
  EXPECT_GT(MeanDifference(first, quarter), 2.0);
  // The server encoded it in its temporary folder and left nothing there.
  EXPECT_TRUE(TemporaryFilesNamed(fmt::format("cinevol-movie-{}-", server_->pid())).empty());
}

TEST_F(MovieCommand, ASweepMovesACutThroughTheVolume) {
  const fs::path out = scratch_ / "sweep.mp4";
  const auto [code, said] = Movie({"--volume", kHead, "--sweep", "axial", "--seconds", "0.5", "--fps", "10", "--width",
                                   "64", "--height", "64", "--spp", "2", "--out", out.string()});
  ASSERT_EQ(code, 0) << said;
  EXPECT_TRUE(Has(Probe(out), "nb_read_frames=5"));
  EXPECT_GT(MeanDifference(Frame(out, 0, scratch_ / "0.png"), Frame(out, 4, scratch_ / "4.png")), 2.0);
}

// A loop of a time series in its own time: at 10 frames/s frame k shows phase k mod 5, so the sphere moves from
// frame to frame and is back where it began after one beat (frames alike in scene and seed are the same still).
TEST_F(MovieCommand, APhasesMovieLoopsTheTimeSeriesInItsOwnTime) {
  const fs::path out = scratch_ / "beat.mp4";
  const auto [code, said] = Movie({"--volume", "beat", "--phases", "--seconds", "1", "--fps", "10", "--width", "64",
                                   "--height", "64", "--spp", "8", "--crf", "0", "--out", out.string()});
  ASSERT_EQ(code, 0) << said;
  EXPECT_TRUE(Has(Probe(out), "nb_read_frames=10"));
  const ImageRgb8 phase0 = Frame(out, 0, scratch_ / "0.png");
  EXPECT_GT(MeanDifference(phase0, Frame(out, 3, scratch_ / "3.png")), 1.0) << "three voxels along";
  EXPECT_LT(MeanDifference(phase0, Frame(out, 5, scratch_ / "5.png")), 0.05) << "phase 0 again";
}

TEST_F(MovieCommand, WhatCannotBeAMovieIsRefusedBeforeAStill) {
  const fs::path out = scratch_ / "refused.mp4";
  auto [code, said] = Movie({"--orbit", "90", "--sweep", "x", "--out", out.string()});
  EXPECT_NE(code, 0);
  EXPECT_TRUE(Has(said, "give one path")) << said;
  std::tie(code, said) = Movie({"--orbit", "90", "--width", "97", "--out", out.string()});
  EXPECT_NE(code, 0);
  EXPECT_TRUE(Has(said, "each side even")) << said;
  std::tie(code, said) = Movie({"--volume", kHead, "--phases", "--out", out.string()});
  EXPECT_NE(code, 0);
  EXPECT_TRUE(Has(said, "holds one phase")) << said;
  std::tie(code, said) = Movie({"--orbit", "90", "--seconds", "600", "--fps", "60", "--out", out.string()});
  EXPECT_NE(code, 0);
  EXPECT_TRUE(Has(said, "36000 frames")) << said;
  std::tie(code, said) = Movie({"--sweep", "diagonal", "--out", out.string()});
  EXPECT_NE(code, 0);
  EXPECT_TRUE(Has(said, "--sweep diagonal")) << said;
}

}  // namespace
}  // namespace cinevol::testing

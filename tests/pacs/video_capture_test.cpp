// Movies as DICOM video (pacs/video_capture.h, issue 58): a stream H264Writer made is a Multi-frame True Color
// Secondary Capture that dciodvfy finds no error in and FFmpeg plays; what is not H.264 within level 4.1 is refused
// naming the field.
#include "pacs/video_capture.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "core/error.h"
#include "support/error_of.h"
#include "support/shell_command.h"
#include "support/test_paths.h"
#include "video/h264_writer.h"

namespace cinevol::pacs {
namespace {

namespace fs = std::filesystem;
using namespace cinevol::testing;

SourceStudy Study() {
  SourceStudy study;
  study.patient_name = "Cinevol^Movie";
  study.patient_id = "CINEVOL-MOVIE-1";
  study.study_uid = "2.25.3400581";
  study.series_uid = "2.25.3400581.1";
  return study;
}

// Frames of a moving gradient as an Annex B stream.
MovieStream Stream(const fs::path& folder, int frames = 5) {
  const fs::path file = folder / "movie.h264";
  {
    H264Writer writer(file, VideoContainer::kAnnexB, {64, 48, 10, 18, true});
    std::vector<std::uint8_t> rgb(64 * 48 * 3);
    for (int f = 0; f < frames; ++f) {
      for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = std::uint8_t((i / 3 % 64) * 4 + f * 10);
      writer.Add(rgb);
    }
    writer.Finish();
  }
  std::ifstream in(file, std::ios::binary);
  return {64, 48, 10, frames, std::string(std::istreambuf_iterator<char>(in), {}), "test"};
}

TEST(MovieCapture, DciodvfyFindsNoErrorAndFfmpegPlaysEveryFrame) {
  ASSERT_TRUE(Installed("dciodvfy") && Installed("ffprobe")) << "run scripts/install-deps.sh";
  ScratchDir scratch;
  SecondaryCaptureUids uids;
  const fs::path file = scratch / "movie.dcm";
  WriteFile(file, MakeMovieCapture(Study(), Stream(scratch.path()), "0.9.0", &uids));
  EXPECT_EQ(uids.study_uid, Study().study_uid);
  const CommandResult checked = RunCommand("dciodvfy '" + file.string() + "'");
  EXPECT_NE(checked.output.find("MultiframeTrueColorSCImage"), std::string::npos) << checked.output;
  EXPECT_EQ(checked.output.find("Error"), std::string::npos) << checked.output;
  const CommandResult probed = RunCommand("ffprobe -v error -count_frames -show_entries stream=codec_name,nb_read_frames "
                                          "-of default=nw=1 '" + file.string() + "'");
  EXPECT_NE(probed.output.find("codec_name=h264"), std::string::npos) << probed.output;
  EXPECT_NE(probed.output.find("nb_read_frames=5"), std::string::npos) << probed.output;
  ASSERT_TRUE(Installed("dcmdump")) << "run scripts/install-deps.sh";
  const CommandResult dumped = RunCommand("dcmdump '" + file.string() + "'");
  for (const char* expected : {"=MPEG4HighProfile/Level4.1", "YBR_PARTIAL_420", "ISO_14496_10", "(0028,0008) IS [5]",
                               "FrameTime"}) {
    EXPECT_NE(dumped.output.find(expected), std::string::npos) << expected << "\n" << dumped.output;
  }
}

TEST(MovieCapture, WhatIsNotH264WithinItsLevelIsRefusedNamingTheField) {
  ScratchDir scratch;
  const MovieStream good = Stream(scratch.path(), 2);
  const auto refused = [&](auto change) {
    MovieStream movie = good;
    change(movie);
    return ErrorOf<InputError>([&] { MakeMovieCapture(Study(), movie, "0.9.0"); });
  };
  EXPECT_NE(refused([](MovieStream& m) { m.width = 65; }).find("movie size"), std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.width = 3840; }).find("1920x1080"), std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.fps = 60; }).find("movie rate"), std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.frames = 0; }).find("movie frames"), std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.h264 = std::string(1000, 'x'); }).find("not an H.264"), std::string::npos);
  const auto slice_without_parameter_sets = [](MovieStream& m) {
    m.h264.assign("\0\0\1\x65", 4);  // appended, not added: GCC 12 warns at -O1 on a sum of temporaries
    m.h264.append(64, 'x');
  };
  EXPECT_NE(refused(slice_without_parameter_sets).find("not an H.264"), std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.description = std::string(49, 'a'); }).find("description"),
            std::string::npos);
  EXPECT_NE(refused([](MovieStream& m) { m.description = "\xc3\xa9"; }).find("description"), std::string::npos);
  EXPECT_NE(ErrorOf<InputError>([&] {
              SourceStudy study = Study();
              study.patient_id = std::string(65, '1');
              MakeMovieCapture(study, good, "0.9.0");
            }).find("patient_id"),
            std::string::npos);
}

}  // namespace
}  // namespace cinevol::pacs

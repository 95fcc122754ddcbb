// Movies (issue 58): frames encoded as H.264 (libx264) through FFmpeg's libraries (Debian's), into an MP4 file for
// people, or an Annex B byte stream for a DICOM video object (MPEG-4 AVC/H.264 High Profile / Level 4.1, PS3.5
// 8.2.8). The client's `cinevol movie` writes one frame at a time as its stills arrive.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

namespace cinevol {

enum class VideoContainer {
  kMp4,    // ISO base media (.mp4)
  kAnnexB  // the raw H.264 byte stream, start codes between NAL units (.h264)
};

struct VideoSettings {
  int width = 0;   // [16; 4096], even (4:2:0 chroma)
  int height = 0;  // [16; 4096], even
  int fps = 25;    // [1; 60]
  // Constant quality (x264's CRF): 0 lossless, 18 visually lossless, 51 worst.
  int crf = 18;
  // Keeps the stream within H.264 High Profile level 4.1 (1920x1080 at 30 frames/s at most), the one DICOM names.
  bool dicom_level = false;
};

class H264Writer {
 public:
  // Opens `path` for writing. InputError for settings out of range (named); std::runtime_error where FFmpeg has no
  // libx264 or cannot open the file.
  H264Writer(const std::filesystem::path& path, VideoContainer container, const VideoSettings& settings);
  ~H264Writer();
  H264Writer(const H264Writer&) = delete;
  H264Writer& operator=(const H264Writer&) = delete;

  // One frame: 8-bit RGB, rows top first, width * height * 3 bytes.
  void Add(const std::vector<std::uint8_t>& rgb);
  // Flushes the encoder and closes the file; the writer takes no frame after.
  void Finish();
  int frames() const { return frames_; }

 private:
  struct Codec;
  std::unique_ptr<Codec> codec_;
  int frames_ = 0;
};

}  // namespace cinevol

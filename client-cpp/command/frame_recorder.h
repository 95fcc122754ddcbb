// Writes what a played session received: frames as JPEG files (all of them,
// or at most a given number per second of the run), a CSV line per frame,
// and a contact sheet of evenly spaced frames.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "script_player.h"

namespace cinevol::cli {

// A frame written to disk: where, when it came (seconds into the run) and
// the samples per pixel behind it.
struct WrittenFrame {
  std::filesystem::path path;
  double at = 0;
  int accumulated_spp = 0;
};

class FrameRecorder {
 public:
  // Frames go to `folder`/frames/, the CSV to `folder`/frames.csv.
  // max_per_second 0 writes every frame; final frames are always written.
  FrameRecorder(const std::filesystem::path& folder, double max_per_second = 0);

  void Add(const ReceivedFrame& received);

  const std::vector<WrittenFrame>& written() const { return written_; }
  const std::filesystem::path& csv_path() const { return csv_path_; }

 private:
  std::filesystem::path frames_dir_, csv_path_;
  std::ofstream csv_;
  double max_per_second_;
  double next_write_at_ = 0;
  std::vector<WrittenFrame> written_;
};

// Up to `count` frames from `frames`, evenly spaced, shrunk to `thumb_width`
// pixels wide and laid out `columns` to a row, each captioned with its time
// and samples per pixel ("12.3 s 64 spp"), as a PNG at `out`.
void WriteContactSheet(const std::vector<WrittenFrame>& frames, const std::filesystem::path& out, int count = 16,
                       int columns = 4, int thumb_width = 320);

}  // namespace cinevol::cli

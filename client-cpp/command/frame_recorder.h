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

class FrameRecorder {
 public:
  // Frames go to `folder`/frames/, the CSV to `folder`/frames.csv.
  // max_per_second 0 writes every frame; final frames are always written.
  FrameRecorder(const std::filesystem::path& folder, double max_per_second = 0);

  void Add(const ReceivedFrame& received);

  const std::vector<std::filesystem::path>& written() const { return written_; }
  const std::filesystem::path& csv_path() const { return csv_path_; }

 private:
  std::filesystem::path frames_dir_, csv_path_;
  std::ofstream csv_;
  double max_per_second_;
  double next_write_at_ = 0;
  std::vector<std::filesystem::path> written_;
};

// Up to `count` frames from `frames`, evenly spaced, shrunk to `thumb_width`
// pixels wide and laid out `columns` to a row, as a PNG at `out`.
void WriteContactSheet(const std::vector<std::filesystem::path>& frames, const std::filesystem::path& out,
                       int count = 16, int columns = 4, int thumb_width = 240);

}  // namespace cinevol::cli

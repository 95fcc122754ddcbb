// FrameRecorder and the contact sheet.
#include "frame_recorder.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>

#include "core/error.h"
#include "encode/image_codecs.h"

namespace cinevol::cli {
namespace {

std::vector<std::uint8_t> ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// Box-filtered shrink to `width` pixels wide, keeping the aspect ratio.
ImageRgb8 Shrink(const ImageRgb8& image, int width) {
  width = std::min(width, image.width);
  const int height = std::max(1, image.height * width / image.width);
  ImageRgb8 out{width, height, std::vector<std::uint8_t>(std::size_t(width) * height * 3)};
  for (int y = 0; y < height; ++y) {
    const int y0 = y * image.height / height, y1 = std::max(y0 + 1, (y + 1) * image.height / height);
    for (int x = 0; x < width; ++x) {
      const int x0 = x * image.width / width, x1 = std::max(x0 + 1, (x + 1) * image.width / width);
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int sy = y0; sy < y1; ++sy) {
          for (int sx = x0; sx < x1; ++sx) sum += image.bytes[(std::size_t(sy) * image.width + sx) * 3 + c];
        }
        out.bytes[(std::size_t(y) * width + x) * 3 + c] = std::uint8_t(sum / ((y1 - y0) * (x1 - x0)));
      }
    }
  }
  return out;
}

// A 3x5 pixel font for the captions: the rows of each glyph, three bits each
// (the high bit leftmost), for the few characters a caption holds.
struct Glyph {
  char c;
  std::uint8_t rows[5];
};
constexpr Glyph kGlyphs[] = {
    {'0', {7, 5, 5, 5, 7}}, {'1', {2, 6, 2, 2, 7}}, {'2', {7, 1, 7, 4, 7}}, {'3', {7, 1, 7, 1, 7}},
    {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 7, 1, 7}}, {'6', {7, 4, 7, 5, 7}}, {'7', {7, 1, 1, 1, 1}},
    {'8', {7, 5, 7, 5, 7}}, {'9', {7, 5, 7, 1, 7}}, {'.', {0, 0, 0, 0, 2}}, {'s', {0, 3, 6, 1, 6}},
    {'p', {0, 6, 5, 6, 4}}, {' ', {0, 0, 0, 0, 0}}};
constexpr int kGlyphScale = 2;  // screen pixels a font pixel

// Writes `text` in white on a dark band at the bottom left of `image`.
void Caption(ImageRgb8& image, const std::string& text) {
  const int advance = 4 * kGlyphScale, height = 5 * kGlyphScale, pad = kGlyphScale;
  const int band_h = std::min(image.height, height + 2 * pad);
  const int band_w = std::min(image.width, int(text.size()) * advance + 2 * pad);
  auto set = [&](int x, int y, std::uint8_t v) {
    if (x < 0 || y < 0 || x >= image.width || y >= image.height) return;
    std::uint8_t* p = &image.bytes[(std::size_t(y) * image.width + x) * 3];
    p[0] = p[1] = p[2] = v;
  };
  const int top = image.height - band_h;
  for (int y = top; y < image.height; ++y) {
    for (int x = 0; x < band_w; ++x) set(x, y, 0);
  }
  for (std::size_t i = 0; i < text.size(); ++i) {
    const Glyph* glyph = std::find_if(std::begin(kGlyphs), std::end(kGlyphs), [&](const Glyph& g) { return g.c == text[i]; });
    if (glyph == std::end(kGlyphs)) continue;
    for (int row = 0; row < 5; ++row) {
      for (int col = 0; col < 3; ++col) {
        if (!(glyph->rows[row] & (4 >> col))) continue;
        for (int dy = 0; dy < kGlyphScale; ++dy) {
          for (int dx = 0; dx < kGlyphScale; ++dx) {
            set(pad + int(i) * advance + col * kGlyphScale + dx, top + pad + row * kGlyphScale + dy, 255);
          }
        }
      }
    }
  }
}

// A frame's image, JPEG or PNG.
ImageRgb8 DecodeFrameFile(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = ReadBytes(path);
  return path.extension() == ".png" ? DecodePng(bytes) : DecodeJpeg(bytes);
}

}  // namespace

FrameRecorder::FrameRecorder(const std::filesystem::path& folder, double max_per_second)
    : frames_dir_(folder / "frames"), csv_path_(folder / "frames.csv"), max_per_second_(max_per_second) {
  std::filesystem::create_directories(frames_dir_);
  csv_.open(csv_path_);
  if (!csv_) throw InputError(fmt::format("{}: cannot write", csv_path_.string()));
  csv_ << "frame_id,received_s,width,height,accumulated_spp,final,last_event_seq,bytes,render_us,denoise_us,"
          "tonemap_us,encode_us,queue_us,server_us,latency_ms,file\n";
}

void FrameRecorder::Add(const ReceivedFrame& r) {
  const v1::Frame& f = r.frame;
  std::string file;
  if (max_per_second_ <= 0 || f.final() || r.at >= next_write_at_) {
    next_write_at_ = r.at + (max_per_second_ > 0 ? 1.0 / max_per_second_ : 0.0);
    const std::filesystem::path path =
        frames_dir_ / fmt::format("frame-{:06}.{}", f.frame_id(), f.has_png() ? "png" : "jpg");
    WriteFile(path, std::vector<std::uint8_t>(EncodedImage(f).begin(), EncodedImage(f).end()));
    written_.push_back({path, r.at, int(f.accumulated_spp())});
    file = path.filename().string();
  }
  const auto& t = f.timings();
  csv_ << fmt::format("{},{:.4f},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", f.frame_id(), r.at, f.width(),
                      f.height(), f.accumulated_spp(), f.final() ? 1 : 0, f.last_event_seq(), EncodedImage(f).size(),
                      t.render_us(), t.denoise_us(), t.tonemap_us(), t.encode_us(), t.queue_us(), t.server_us(),
                      r.latency_ms > 0 ? fmt::format("{:.3f}", r.latency_ms) : std::string(), file);
}

void WriteContactSheet(const std::vector<WrittenFrame>& frames, const std::filesystem::path& out, int count,
                       int columns, int thumb_width) {
  if (frames.empty()) throw InputError("no frames for a contact sheet");
  const int n = std::min<int>(count, static_cast<int>(frames.size()));
  std::vector<ImageRgb8> thumbs;
  for (int i = 0; i < n; ++i) {
    const WrittenFrame& frame = frames[n == 1 ? frames.size() - 1 : std::size_t(i) * (frames.size() - 1) / (n - 1)];
    thumbs.push_back(Shrink(DecodeFrameFile(frame.path), thumb_width));
    Caption(thumbs.back(), fmt::format("{:.1f} s {} spp", frame.at, frame.accumulated_spp));
  }
  constexpr int kGap = 4;
  const int cols = std::min(columns, n), rows = (n + cols - 1) / cols;
  const int tw = thumbs[0].width, th = thumbs[0].height;
  ImageRgb8 sheet{cols * tw + (cols + 1) * kGap, rows * th + (rows + 1) * kGap, {}};
  sheet.bytes.assign(std::size_t(sheet.width) * sheet.height * 3, 32);
  for (int i = 0; i < n; ++i) {
    const ImageRgb8& t = thumbs[i];
    const int ox = kGap + (i % cols) * (tw + kGap), oy = kGap + (i / cols) * (th + kGap);
    for (int y = 0; y < std::min(t.height, th); ++y) {
      std::copy_n(&t.bytes[std::size_t(y) * t.width * 3], std::min(t.width, tw) * 3,
                  &sheet.bytes[(std::size_t(oy + y) * sheet.width + ox) * 3]);
    }
  }
  WriteFile(out, EncodePng(sheet));
}

}  // namespace cinevol::cli

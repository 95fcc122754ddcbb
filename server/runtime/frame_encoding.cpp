#include "runtime/frame_encoding.h"

#include <algorithm>

#include "encode/image_codecs.h"
#include "runtime/metrics.h"

namespace cinevol::service {
namespace {

using Clock = std::chrono::steady_clock;

std::uint32_t Micros(double ms) { return static_cast<std::uint32_t>(std::max(0.0, ms * 1000.0)); }

}  // namespace

std::uint32_t MicrosBetween(Clock::time_point from, Clock::time_point to) {
  return static_cast<std::uint32_t>(std::chrono::duration_cast<std::chrono::microseconds>(to - from).count());
}

v1::Frame EncodeFrame(const DisplayFrame& display, const FrameStamp& stamp, int bands) {
  v1::Frame frame;
  const Clock::time_point start = Clock::now();
  if (!display.final_rgb.bytes.empty()) {
    const std::vector<std::uint8_t> png = EncodePng(display.final_rgb);
    frame.set_png(png.data(), png.size());
    frame.set_width(display.final_rgb.width);
    frame.set_height(display.final_rgb.height);
  } else if (!display.jpeg.bytes.empty()) {  // encoded on the GPU already
    frame.set_jpeg(display.jpeg.bytes.data(), display.jpeg.bytes.size());
    frame.set_width(display.jpeg.width);
    frame.set_height(display.jpeg.height);
  } else {
    const std::vector<std::uint8_t> jpeg = EncodeJpeg(display.image, display.jpeg_quality, bands);
    frame.set_jpeg(jpeg.data(), jpeg.size());
    frame.set_width(display.image.width);
    frame.set_height(display.image.height);
  }
  // The size it shows at: the viewport, where the image came smaller
  // (FrameSettings::frames_at_rendered_size).
  if (display.width > 0) {
    frame.set_width(display.width);
    frame.set_height(display.height);
  }
  // The GPU's encode counts as the encode stage, not the display's.
  const double encode_s = std::chrono::duration<double>(Clock::now() - start).count() + display.encode_ms / 1000.0;
  frame.mutable_timings()->set_encode_us(Micros(encode_s * 1000.0));
  ServerMetrics().ObserveStage(Stage::kEncode, encode_s);
  frame.set_frame_id(stamp.frame_id);
  frame.set_accumulated_spp(display.accumulated_spp);
  frame.set_last_event_seq(stamp.event_seq);
  frame.set_final(display.final);
  frame.set_resolution_scale(display.resolution_scale);
  frame.set_phase(stamp.phase);
  frame.set_estimated_error(std::max(display.estimated_error, 0.0f));
  v1::FrameTimings* t = frame.mutable_timings();
  t->set_render_us(Micros(display.render_ms));
  t->set_denoise_us(Micros(display.denoise_ms));
  t->set_tonemap_us(Micros(display.display_ms));
  t->set_queue_us(stamp.queue_us);
  return frame;
}

}  // namespace cinevol::service

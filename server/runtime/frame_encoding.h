// The encode stage of a streamed frame: a displayed frame becomes the
// Frame message a viewer gets (JPEG, or PNG for a lossless final frame),
// with its header and timings. Runs on the encoder pool, never under a
// session's lock.
#pragma once

#include <chrono>
#include <cstdint>

#include "cinevol/v1/service.pb.h"
#include "pipeline/frame_pipeline.h"

namespace cinevol::service {

// What a frame answers and when its work began, for its header and timings.
struct FrameStamp {
  std::uint64_t frame_id = 0;
  std::uint64_t event_seq = 0;
  bool answers_event = false;                 // it applies an event no earlier frame applied
  std::chrono::steady_clock::time_point origin;  // that event's arrival, or the render's start when refining
  std::uint32_t queue_us = 0;                 // from the event's arrival to the render's start
  std::uint32_t phase = 0;                    // of a time series, shown
};

// The frame message for `display`: its image at its jpeg_quality (JPEG in up
// to `bands` bands on idle threads; the JPEG the GPU made where it carries
// one; the final frame as PNG where it carries one), the stamp's header and
// every stage's time. Throws what the encoder throws.
v1::Frame EncodeFrame(const DisplayFrame& display, const FrameStamp& stamp, int bands);

std::uint32_t MicrosBetween(std::chrono::steady_clock::time_point from, std::chrono::steady_clock::time_point to);

}  // namespace cinevol::service

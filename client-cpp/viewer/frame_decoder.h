// The viewer's frame decoder: a thread that decodes the newest frame the
// stream handed it and keeps only the newest decoded one, so that a slow
// decoder skips frames rather than queueing them behind the picture.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "client.h"

namespace cinevol::viewer {

// A decoded frame and what the server said about it.
struct ViewFrame {
  RgbImage image;
  v1::Frame info;               // without its image
  std::size_t image_bytes = 0;  // encoded, as received
  double decode_ms = 0;
  std::chrono::steady_clock::time_point received;
};

class FrameDecoder {
 public:
  // `on_error` hears of a frame that would not decode (on the decoder's thread).
  explicit FrameDecoder(std::function<void(const std::string&)> on_error);
  ~FrameDecoder();  // stops the thread
  FrameDecoder(const FrameDecoder&) = delete;
  FrameDecoder& operator=(const FrameDecoder&) = delete;

  // A frame from the stream (any thread): replaces one not yet decoded.
  void Offer(v1::Frame frame);
  // The newest decoded frame since the last call, if any.
  std::optional<ViewFrame> Take();

 private:
  void Run();

  const std::function<void(const std::string&)> on_error_;
  std::mutex mu_;
  std::condition_variable arrived_;
  bool stopping_ = false;
  std::optional<v1::Frame> encoded_;  // newest undecoded
  std::chrono::steady_clock::time_point encoded_at_;
  std::optional<ViewFrame> decoded_;  // newest decoded, not yet taken
  std::thread thread_;
};

}  // namespace cinevol::viewer

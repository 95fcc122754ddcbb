// The newest-wins JPEG (or PNG) decoder beside the stream's reader.
#include "viewer/frame_decoder.h"

namespace cinevol::viewer {

using Clock = std::chrono::steady_clock;

FrameDecoder::FrameDecoder(std::function<void(const std::string&)> on_error)
    : on_error_(std::move(on_error)), thread_([this] { Run(); }) {}

FrameDecoder::~FrameDecoder() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  arrived_.notify_all();
  thread_.join();
}

void FrameDecoder::Offer(v1::Frame frame) {
  {
    std::lock_guard lock(mu_);
    encoded_ = std::move(frame);
    encoded_at_ = Clock::now();
  }
  arrived_.notify_one();
}

std::optional<ViewFrame> FrameDecoder::Take() {
  std::lock_guard lock(mu_);
  return std::exchange(decoded_, std::nullopt);
}

void FrameDecoder::Run() {
  std::unique_lock lock(mu_);
  for (;;) {
    arrived_.wait(lock, [this] { return encoded_.has_value() || stopping_; });
    if (stopping_) return;
    v1::Frame frame = std::move(*encoded_);
    encoded_.reset();
    const Clock::time_point received = encoded_at_;
    lock.unlock();
    ViewFrame view;
    const auto start = Clock::now();
    try {
      view.image = DecodeFrame(frame);
    } catch (const std::exception& e) {
      on_error_(std::string("a frame could not be decoded: ") + e.what());
      lock.lock();
      continue;
    }
    view.decode_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    view.image_bytes = EncodedImage(frame).size();
    frame.clear_image();
    view.info = std::move(frame);
    view.received = received;
    lock.lock();
    decoded_ = std::move(view);
  }
}

}  // namespace cinevol::viewer

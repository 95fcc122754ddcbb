// The CPU half of the launch backends: host buffers and a parallel loop over
// pixels. device/cuda_backend.cuh is the GPU half with the same shape, so the
// denoisers (denoise/denoisers.h), the display and the upsampler
// (pipeline/) are written once over either.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/parallel_for.h"
#include "device/frame_scratch.h"

namespace cinevol {

// How far a row window may reach either side (RowWindowSums), on either
// backend: a GPU block holds its segment's taps and that much more in
// shared memory.
inline constexpr int kMaxRowReach = 32;

inline void CheckRowReach(int radius, int stride) {
  if (radius < 0 || stride < 1 || radius * stride > kMaxRowReach) {
    throw std::invalid_argument("RowWindowSums: a window of radius " + std::to_string(radius) + " and stride " +
                                std::to_string(stride) + " (needs radius >= 0, stride >= 1 and a reach of at most " +
                                std::to_string(kMaxRowReach) + " pixels)");
  }
}

struct CpuBackend {
  template <class T>
  class Buffer {
   public:
    void Resize(std::size_t count) { data_.resize(count); }
    void Zero() { std::fill(data_.begin(), data_.end(), T{}); }
    void CopyFrom(const T* src, std::size_t count) { data_.assign(src, src + count); }
    std::vector<T> Download() const { return data_; }
    void Download(T* host) const { std::copy(data_.begin(), data_.end(), host); }
    T* data() { return data_.data(); }
    const T* data() const { return data_.data(); }
    std::size_t size() const { return data_.size(); }

   private:
    std::vector<T> data_;
  };
  // Host memory that Buffer::Download(T*) fills.
  template <class T>
  using HostBuffer = Buffer<T>;
  // `count` elements of this thread's scratch for `role` (frame_scratch.h).
  template <class T>
  static T* FrameScratch(Scratch role, std::size_t count) {
    return static_cast<T*>(HostScratch(role, count * sizeof(T)));
  }

  // f(x, y) for every pixel; f must not throw. Frames too small to repay
  // starting threads run on the caller's.
  template <class F>
  static void ForEachPixel(int width, int height, const F& f) {
    ParallelFor(height, [&](std::int64_t y) {
      for (int x = 0; x < width; ++x) f(x, int(y));
    }, std::int64_t(width) * height < kMinPixelsPerThread ? 1 : 0);
  }

  static constexpr std::int64_t kMinPixelsPerThread = 16384;

  // Sums of a per-pixel quantity along each row: out[y * width + x] = the
  // sum of tap(x + stride * k, y) for k = -radius..radius, in that order,
  // taps beyond the row adding nothing. The windows overlap, so each tap is
  // evaluated once (on a GPU, once per row segment that reads it) and may
  // cost what a pixel's share of work costs.
  // radius * stride <= kMaxRowReach.
  template <class Tap, class T>
  static void RowWindowSums(int width, int height, int radius, int stride, const Tap& tap, T* out) {
    CheckRowReach(radius, stride);
    ParallelFor(height, [&](std::int64_t row) {
      thread_local std::vector<T> taps;
      taps.resize(std::size_t(width));
      const int y = int(row);
      for (int x = 0; x < width; ++x) taps[std::size_t(x)] = tap(x, y);
      for (int x = 0; x < width; ++x) {
        T sum{};
        for (int k = -radius; k <= radius; ++k) {
          const int nx = x + stride * k;
          if (nx >= 0 && nx < width) sum = sum + taps[std::size_t(nx)];
        }
        out[std::size_t(y) * width + x] = sum;
      }
    }, std::int64_t(width) * height < kMinPixelsPerThread ? 1 : 0);
  }

  // A frame's histogram: bins[b] = how many pixels bin(x, y) puts in b
  // (a bin below 0 or from kBins up counts nowhere), counted from 0. The
  // counts are integers, the same whatever thread counted a row.
  template <int kBins, class Bin>
  static void CountInBins(int width, int height, const Bin& bin, unsigned* bins) {
    std::fill(bins, bins + kBins, 0u);
    std::mutex merge;
    ParallelFor(height, [&](std::int64_t y) {
      std::array<unsigned, kBins> row{};
      for (int x = 0; x < width; ++x) {
        const int b = bin(x, int(y));
        if (b >= 0 && b < kBins) ++row[std::size_t(b)];
      }
      const std::lock_guard<std::mutex> lock(merge);
      for (int b = 0; b < kBins; ++b) bins[b] += row[std::size_t(b)];
    }, std::int64_t(width) * height < kMinPixelsPerThread ? 1 : 0);
  }

  // Wall-clock timing of a sequence of passes.
  class Timer {
   public:
    void Start() { start_ = std::chrono::steady_clock::now(); }
    void Stop() { ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count(); }
    double Milliseconds() const { return ms_; }

   private:
    std::chrono::steady_clock::time_point start_;
    double ms_ = 0;
  };
};

}  // namespace cinevol

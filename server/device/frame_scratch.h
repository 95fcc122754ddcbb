// Frame scratch: the buffers a frame needs only while it is made (the
// render's outputs, the denoiser's a-trous pair, its row sums and edge
// guides, the refinement's planes), held by the frames being made rather
// than by every session.
//
// A frame takes a set of them for its span and gives it back, so the sets
// number the frames that run at once, not the sessions: a 720p session
// holds 210 MiB of the GPU, not 330 (docs/performance.md, "Frame scratch
// from a pool").
// On the GPU a session's frame (FramePipeline) takes a set from the GPU's
// pool, sized by the frame's pixels (FrameScratchScope); outside one (tests
// and benches driving a renderer or denoiser directly) and on the CPU, a
// thread has its own set: a thread makes one frame at a time.
#pragma once

#include <cstddef>

namespace cinevol {

// What a scratch buffer holds. A pointer to one stays valid, and its
// contents the frame's, until the frame's scope ends or, outside one, the
// thread asks for the same role again: each role has one writer a frame.
enum class Scratch : int {
  kRadiance,           // the render's outputs, read by the denoiser and the refinement
  kFirstHit,
  kAlbedo,
  kSurfaceNormal,      // FrameTargets::surface_normal, where a frame asks for it
  kEstimate,           // the denoiser's a-trous pair: prediction and variance
  kEstimateNext,
  kOutputHistory,      // wRLS: the previous output, reprojected
  kPreviousPixel,      // wRLS: where each pixel was in the previous frame
  kRowSums,            // wRLS: a recentering or rescaling window's row sums
  kEdgeGuides,         // the a-trous levels' edge guides, and their row sums
  kEdgeRowHits,
  kDemodulated,        // a demodulating denoiser's input
  kRefinePlanes,       // the refinement's blend (pipeline/refine.h): six float planes,
  kRefineHalves,       // the two halves' means and their ping-pong,
  kRefineEstimate,     // and the estimate
};
inline constexpr int kScratchRoles = int(Scratch::kRefineEstimate) + 1;

// While it lives, this thread's GPU scratch is a set of the current GPU's
// pool for a frame of `pixels`, which the frame's work on this thread's
// stream (cudaStreamPerThread) may use; the next frame to take the set waits
// for that work on its own stream. Only for frames on a GPU.
class FrameScratchScope {
 public:
  explicit FrameScratchScope(std::size_t pixels);
  ~FrameScratchScope();
  FrameScratchScope(const FrameScratchScope&) = delete;
  FrameScratchScope& operator=(const FrameScratchScope&) = delete;

 private:
  std::size_t pixels_;
  void* pool_;      // the GPU's pool
  void* set_;       // the set taken from it
  void* previous_;  // the set it replaced on this thread
};

// This thread's host buffer for `role`: at least `bytes`, 16-byte aligned,
// grown when a frame needs more and never shrunk (a thread's largest frame
// sets it).
void* HostScratch(Scratch role, std::size_t bytes);

}  // namespace cinevol

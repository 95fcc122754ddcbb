// Frame scratch: the buffers a frame needs only while it is made (the
// render's outputs, the denoiser's a-trous pair, its row sums and edge
// guides), kept per thread rather than per session.
//
// A thread makes one frame at a time from start to end (a scheduler
// worker's step, a still, a test), so one buffer per role and thread serves
// every session whose frames that thread makes. Past a few sessions the
// memory a frame touches is then the workers' scratch plus its own
// session's histories, not every session's copy of both: a session holds a
// third less device memory, and frames find their scratch warm in the
// GPU's caches and address translations (docs/performance.md, "Frame
// scratch per worker").
#pragma once

#include <cstddef>

namespace cinevol {

// What a scratch buffer holds. A pointer to one stays valid, and its
// contents the frame's, until the same thread asks for the same role again:
// each role has one writer a frame.
enum class Scratch : int {
  kRadiance,           // the render's outputs, read by the denoiser and the refinement
  kFirstHit,
  kAlbedo,
  kEstimate,           // the denoiser's a-trous pair: prediction and variance
  kEstimateNext,
  kOutputHistory,      // wRLS: the previous output, reprojected
  kPreviousPixel,      // wRLS: where each pixel was in the previous frame
  kRowSums,            // wRLS: a recentering or rescaling window's row sums
  kEdgeGuides,         // the a-trous levels' edge guides, and their row sums
  kEdgeRowHits,
  kDemodulated,        // a demodulating denoiser's input
};
inline constexpr int kScratchRoles = int(Scratch::kDemodulated) + 1;

// This thread's host buffer for `role`: at least `bytes`, 16-byte aligned,
// grown when a frame needs more and never shrunk (a thread's largest frame
// sets it).
void* HostScratch(Scratch role, std::size_t bytes);

}  // namespace cinevol

// PhaseCopies: the device copies of a time series' phases that one session
// holds (the volume cache's, shared with every session of the series on that
// device). Every phase where the series fits the session's budget
// (SessionLimits::max_phase_copy_bytes); else a window: the phase shown and
// those after it in play order, as many as the budget holds, the ones ahead
// built on a task so that a switch finds its phase there.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "render/prepared_volume.h"
#include "render/renderer.h"
#include "runtime/task_pool.h"
#include "runtime/volume_registry.h"

namespace cinevol::service {

// Every session's renderer: default bricks, the volume texture where it fits.
inline const RendererOptions kSessionRenderer{};

// `volume`'s copy on `device` as a session's renderer asks for it (the volume
// cache's: built on first use, shared).
std::shared_ptr<const VolumeCopy> CopyOf(const std::shared_ptr<const Volume>& volume, int device);

class PhaseCopies {
 public:
  // The phases of `series` a budget of `budget_bytes` holds on `device`,
  // its first phase's copy built (or found) here: all of them, or a window
  // of two or more. Throws LimitExceeded (--max-phase-copies-mb) where it
  // holds fewer than two of several phases; ResourceExhausted where the
  // device is full.
  static int Window(const VolumeLease& series, int device, std::uint64_t budget_bytes);

  // Holds `window` phases from `first` (Window's), built now where the cache
  // does not hold them: slow, so callers keep off the frame workers where
  // they can. Later windows are built ahead on `prefetch` (queue `queue`),
  // or at once where it is null.
  PhaseCopies(const VolumeLease& series, int device, int window, TaskPool* prefetch, std::string queue, int first);
  ~PhaseCopies();

  // Holds `phase`'s copy (built now where it is not held) and the window
  // after it; releases the rest.
  void ShowFrom(int phase);
  int window() const;

 private:
  struct Held;  // shared with the tasks that build ahead
  static void BuildAhead(const std::shared_ptr<Held>& held);

  std::shared_ptr<Held> held_;
  TaskPool* prefetch_;
  std::string queue_;
};

}  // namespace cinevol::service

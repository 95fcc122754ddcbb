// PhaseCopies: a time series' phases on the device, all or a window ahead.
#include "runtime/phase_copies.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

#include "runtime/errors.h"

namespace cinevol::service {
namespace {


}  // namespace

std::shared_ptr<const VolumeCopy> CopyOf(const std::shared_ptr<const Volume>& phase, int device) {
  return VolumeCache::Get().Acquire(phase, kSessionRenderer.brick_size, device, kSessionRenderer.volume_texture);
}

struct PhaseCopies::Held {
  std::vector<std::shared_ptr<const Volume>> phases;
  int device = 0;
  int window = 1;
  std::mutex mu;
  std::vector<int> wanted;                                  // the window, in play order
  std::map<int, std::shared_ptr<const VolumeCopy>> copies;  // by phase
  bool building = false;                                    // a task building ahead is queued or running
  bool ended = false;                                       // the session let go: build nothing more

  // The first phase of the window not held, or -1. mu held.
  int NextMissingLocked() const {
    for (int k : wanted) {
      if (!copies.count(k)) return k;
    }
    return -1;
  }
};

int PhaseCopies::Window(const VolumeLease& series, int device, std::uint64_t budget_bytes) {
  const int phases = series.phases();
  const std::uint64_t bytes = std::max<std::size_t>(1, CopyOf(series.phase(0), device)->bytes());
  const int window = int(std::min<std::uint64_t>(std::uint64_t(phases), budget_bytes / bytes));
  if (phases > 1 && window < 2) {
    throw LimitExceeded("max-phase-copies-mb",
                        fmt::format("a phase of this time series takes {} on the device; the budget of {} a session "
                                    "holds in phase copies (--max-phase-copies-mb) holds {} of its {} phases, and "
                                    "playing needs two",
                                    Mib(bytes), Mib(budget_bytes), window, phases));
  }
  return std::max(1, window);
}

PhaseCopies::PhaseCopies(const VolumeLease& series, int device, int window, TaskPool* prefetch, std::string queue,
                         int first)
    : held_(std::make_shared<Held>()), prefetch_(prefetch), queue_(std::move(queue)) {
  for (int k = 0; k < series.phases(); ++k) held_->phases.push_back(series.phase(k));
  held_->device = device;
  held_->window = std::clamp(window, 1, series.phases());
  std::vector<int> order;
  for (int i = 0; i < held_->window; ++i) order.push_back((first + i) % series.phases());
  for (int k : order) held_->copies[k] = CopyOf(held_->phases[std::size_t(k)], device);
  held_->wanted = std::move(order);
}

PhaseCopies::~PhaseCopies() {
  std::lock_guard lock(held_->mu);
  held_->ended = true;
  held_->copies.clear();  // a task still running drops what it builds
}

int PhaseCopies::window() const { return held_->window; }

void PhaseCopies::ShowFrom(int phase) {
  const int phases = int(held_->phases.size());
  phase = std::clamp(phase, 0, phases - 1);
  bool have = false;
  {
    std::lock_guard lock(held_->mu);
    held_->wanted.clear();
    for (int i = 0; i < held_->window; ++i) held_->wanted.push_back((phase + i) % phases);
    std::erase_if(held_->copies, [&](const auto& c) {
      return std::find(held_->wanted.begin(), held_->wanted.end(), c.first) == held_->wanted.end();
    });
    have = held_->copies.count(phase) > 0;
  }
  if (!have) {  // a jump out of the window: this frame waits for its phase
    auto copy = CopyOf(held_->phases[std::size_t(phase)], held_->device);
    std::lock_guard lock(held_->mu);
    held_->copies[phase] = std::move(copy);
  }
  {
    std::lock_guard lock(held_->mu);
    if (held_->building || held_->NextMissingLocked() < 0) return;
    held_->building = true;
  }
  if (!prefetch_ || !prefetch_->Submit([held = held_] { BuildAhead(held); }, queue_)) BuildAhead(held_);
}

void PhaseCopies::BuildAhead(const std::shared_ptr<Held>& held) {
  for (;;) {
    int k;
    {
      std::lock_guard lock(held->mu);
      k = held->ended ? -1 : held->NextMissingLocked();
      if (k < 0) {
        held->building = false;
        return;
      }
    }
    std::shared_ptr<const VolumeCopy> copy;
    try {
      copy = CopyOf(held->phases[std::size_t(k)], held->device);
    } catch (const std::exception& e) {  // the switch builds it itself, and reports what fails then
      spdlog::warn("a time series' phase {} not built ahead: {}", k, e.what());
      std::lock_guard lock(held->mu);
      held->building = false;
      return;
    }
    std::lock_guard lock(held->mu);
    const bool wanted = std::find(held->wanted.begin(), held->wanted.end(), k) != held->wanted.end();
    if (wanted && !held->ended) held->copies[k] = std::move(copy);
  }
}

}  // namespace cinevol::service

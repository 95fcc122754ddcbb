// CallWatch: deadlines for calls that must keep moving.
#include "service/call_watch.h"

namespace cinevol::service {

CallWatch::Id CallWatch::Watch(grpc::CallbackServerContext* context, Clock::duration patience,
                               std::atomic<bool>* overdue) {
  std::lock_guard lock(mu_);
  const Id id = next_++;
  calls_[id] = {context, Clock::now() + patience, overdue};
  return id;
}

void CallWatch::Touch(Id id, Clock::duration patience) {
  std::lock_guard lock(mu_);
  auto it = calls_.find(id);
  if (it != calls_.end()) it->second.deadline = Clock::now() + patience;
}

void CallWatch::Forget(Id id) {
  std::lock_guard lock(mu_);
  calls_.erase(id);
}

void CallWatch::CancelOverdue(Clock::time_point now) {
  // Under the lock: a reactor forgets its call before it is deleted, so every
  // context and flag here is alive. TryCancel only marks the call; the
  // reactor's OnCancel and OnDone run later on gRPC's threads.
  std::lock_guard lock(mu_);
  for (auto it = calls_.begin(); it != calls_.end();) {
    if (it->second.deadline <= now) {
      if (it->second.overdue) {
        it->second.overdue->store(true);
      } else {
        it->second.context->TryCancel();
      }
      it = calls_.erase(it);
    } else {
      ++it;
    }
  }
}

std::size_t CallWatch::watched() const {
  std::lock_guard lock(mu_);
  return calls_.size();
}

}  // namespace cinevol::service

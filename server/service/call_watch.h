// Calls that must keep moving: a stream that sends no attach, an upload that
// stops sending. Each is watched with a deadline that its progress pushes
// back; the server's sweep cancels the calls past theirs, so a client that
// opens calls and goes quiet cannot hold memory or a slot for long.
#pragma once

#include <grpcpp/server_context.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>

namespace cinevol::service {

class CallWatch {
 public:
  using Clock = std::chrono::steady_clock;
  using Id = std::uint64_t;

  // Watches `context` until Forget; it is cancelled once `patience` passes
  // without a Touch.
  Id Watch(grpc::CallbackServerContext* context, Clock::duration patience);
  void Touch(Id id, Clock::duration patience);
  // Call before the reactor is deleted (OnDone at the latest).
  void Forget(Id id);
  // Cancels the calls past their deadline (gRPC then finishes them).
  void CancelOverdue(Clock::time_point now);
  std::size_t watched() const;

 private:
  struct Entry {
    grpc::CallbackServerContext* context;
    Clock::time_point deadline;
  };
  mutable std::mutex mu_;
  std::map<Id, Entry> calls_;
  Id next_ = 1;
};

// Seconds as a Clock::duration.
inline CallWatch::Clock::duration Seconds(double s) {
  return std::chrono::duration_cast<CallWatch::Clock::duration>(std::chrono::duration<double>(s));
}

}  // namespace cinevol::service

// Calls that must keep moving or end: a stream that sends no attach, an
// upload that stops sending, a unary call's work past the server's deadline.
// Each is watched with a deadline that its progress may push back; the
// server's sweep (five times a second) cancels the calls past theirs, so a
// client that opens calls and goes quiet, or asks for endless work, cannot
// hold memory, a slot or a worker for long.
#pragma once

#include <grpcpp/server_context.h>

#include <atomic>
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
  // without a Touch. With `overdue`, that flag is raised instead: the call's
  // own work sees it, stops and finishes the call with DEADLINE_EXCEEDED.
  Id Watch(grpc::CallbackServerContext* context, Clock::duration patience, std::atomic<bool>* overdue = nullptr);
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
    std::atomic<bool>* overdue;
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

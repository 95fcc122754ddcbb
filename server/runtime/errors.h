// Errors at the service boundary. Code below the service throws InputError
// and ResourceExhausted (core/error.h); the service adds RpcError for the
// codes only it knows (NOT_FOUND, PERMISSION_DENIED, ...). ToStatus is the
// one place where any of them becomes the grpc::Status a caller sees.
#pragma once

#include <grpcpp/support/status.h>

#include <exception>
#include <stdexcept>
#include <string>

#include "core/error.h"

namespace cinevol::service {

class RpcError : public std::runtime_error {
 public:
  RpcError(grpc::StatusCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  grpc::StatusCode code() const { return code_; }
  grpc::Status status() const { return {code_, what()}; }

 private:
  grpc::StatusCode code_;
};

// A request over one of the server's limits: `flag` names it ("max-lights")
// for the metrics; the message names the flag and value for the caller.
class LimitExceeded : public RpcError {
 public:
  LimitExceeded(grpc::StatusCode code, std::string flag, const std::string& message)
      : RpcError(code, message), flag_(std::move(flag)) {}
  const std::string& flag() const { return flag_; }

 private:
  std::string flag_;
};

// InputError -> INVALID_ARGUMENT, ResourceExhausted and bad_alloc ->
// RESOURCE_EXHAUSTED, RpcError -> its code, anything else -> INTERNAL.
grpc::Status ToStatus(std::exception_ptr error);

// Runs `f`, returning OK or the status of what it threw.
template <class F>
grpc::Status Guarded(F&& f) {
  try {
    f();
    return grpc::Status::OK;
  } catch (...) {
    return ToStatus(std::current_exception());
  }
}

}  // namespace cinevol::service

// Errors at the service boundary. Code below the service throws InputError
// and ResourceExhausted (core/error.h); the service adds RpcError for the
// codes only it knows (NOT_FOUND, PERMISSION_DENIED, ...). ToStatus is the
// one place where any of them becomes the grpc::Status a caller sees.
#pragma once

#include <grpcpp/support/status.h>

#include <exception>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/error.h"

namespace cinevol::service {

// The codes the service makes itself, one named constructor each: throw
// `RpcError::NotFound("...")`, or answer `RpcError::NotFound("...").status()`
// where a status is handed on rather than thrown.
class RpcError : public std::runtime_error {
 public:
  static RpcError InvalidArgument(const std::string& m) { return {grpc::StatusCode::INVALID_ARGUMENT, m}; }
  static RpcError NotFound(const std::string& m) { return {grpc::StatusCode::NOT_FOUND, m}; }
  static RpcError PermissionDenied(const std::string& m) { return {grpc::StatusCode::PERMISSION_DENIED, m}; }
  static RpcError Unauthenticated(const std::string& m) { return {grpc::StatusCode::UNAUTHENTICATED, m}; }
  static RpcError FailedPrecondition(const std::string& m) { return {grpc::StatusCode::FAILED_PRECONDITION, m}; }
  static RpcError Aborted(const std::string& m) { return {grpc::StatusCode::ABORTED, m}; }
  static RpcError Unavailable(const std::string& m) { return {grpc::StatusCode::UNAVAILABLE, m}; }
  static RpcError DeadlineExceeded(const std::string& m) { return {grpc::StatusCode::DEADLINE_EXCEEDED, m}; }
  static RpcError Cancelled(const std::string& m) { return {grpc::StatusCode::CANCELLED, m}; }

  grpc::StatusCode code() const { return code_; }
  grpc::Status status() const { return {code_, what()}; }

 protected:
  RpcError(grpc::StatusCode code, const std::string& message) : std::runtime_error(message), code_(code) {}

 private:
  grpc::StatusCode code_;
};

// A request over one of the server's limits (RESOURCE_EXHAUSTED): `flag`
// names it ("max-lights") for the metrics; the message names the flag and
// value for the caller.
class LimitExceeded : public RpcError {
 public:
  LimitExceeded(std::string flag, const std::string& message)
      : RpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, message), flag_(std::move(flag)) {}
  const std::string& flag() const { return flag_; }

 private:
  std::string flag_;
};

// Not an error: OK that still says why a call ended (a session its owner closed).
inline grpc::Status OkStatus(const std::string& message) { return {grpc::StatusCode::OK, message}; }

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

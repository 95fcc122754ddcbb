// Exceptions to gRPC status codes, in one place.
#include "runtime/errors.h"

#include <spdlog/spdlog.h>

#include <new>

#include "core/error.h"
#include "core/log_safe.h"
#include "pacs/pacs_error.h"
#include "runtime/metrics.h"

namespace cinevol::service {

namespace {

grpc::Status StatusOf(std::exception_ptr error) {
  try {
    std::rethrow_exception(error);
  } catch (const LimitExceeded& e) {
    ServerMetrics().LimitRefused(e.flag());
    return e.status();
  } catch (const RpcError& e) {
    return e.status();
  } catch (const OverLimit& e) {
    ServerMetrics().LimitRefused(e.flag());
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
  } catch (const InputError& e) {
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
  } catch (const Cancelled& e) {
    return {grpc::StatusCode::CANCELLED, e.what()};
  } catch (const pacs::PacsError& e) {
    // The PACS is down, slow or failing: another try may succeed. What it
    // answered in words (a missing series, refused credentials) may not.
    const bool transient = e.http_status() == 0 || e.http_status() >= 500;
    return {e.http_status() == 404 ? grpc::StatusCode::NOT_FOUND
            : transient           ? grpc::StatusCode::UNAVAILABLE
                                  : grpc::StatusCode::FAILED_PRECONDITION,
            e.what()};
  } catch (const ResourceExhausted& e) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, e.what()};
  } catch (const std::bad_alloc&) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "out of host memory"};
  } catch (const std::exception& e) {
    // The detail (a library's words, a server path) is for the operator's log only.
    spdlog::error("internal error: {}", LogSafe(e.what()));
    return {grpc::StatusCode::INTERNAL, "internal error; the server's log has the detail"};
  } catch (...) {
    spdlog::error("internal error of unknown type");
    return {grpc::StatusCode::INTERNAL, "internal error"};
  }
}

}  // namespace

grpc::Status ToStatus(std::exception_ptr error) {
  grpc::Status status = StatusOf(std::move(error));
  ServerMetrics().Error(status.error_code());  // every error a caller sees passes here
  return status;
}

}  // namespace cinevol::service

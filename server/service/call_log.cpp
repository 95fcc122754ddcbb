// The access log interceptor.
#include "service/call_log.h"

#include <fmt/format.h>
#include <grpcpp/server_context.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <string>

#include "core/log_safe.h"

namespace cinevol::service {
namespace {

using grpc::experimental::InterceptionHookPoints;

std::string StatusName(grpc::StatusCode code) {
  static const char* kNames[] = {"OK",        "CANCELLED",         "UNKNOWN",          "INVALID_ARGUMENT",
                                 "DEADLINE_EXCEEDED", "NOT_FOUND", "ALREADY_EXISTS",   "PERMISSION_DENIED",
                                 "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION", "ABORTED", "OUT_OF_RANGE",
                                 "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  const int i = int(code);
  return i >= 0 && i < int(std::size(kNames)) ? kNames[i] : std::to_string(i);
}

class CallLog final : public grpc::experimental::Interceptor {
 public:
  explicit CallLog(grpc::experimental::ServerRpcInfo* info) : info_(info) {
    static std::atomic<std::uint64_t> next{1};
    id_ = next++;
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      methods->GetSendTrailingMetadata()->emplace("cinevol-request-id", std::to_string(id_));
      const grpc::Status status = methods->GetSendStatus();
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
      std::string method = info_->method();
      if (method.rfind("/cinevol.v1.", 0) == 0) method = method.substr(12);
      const auto level = status.ok() || status.error_code() == grpc::StatusCode::CANCELLED ? spdlog::level::debug
                                                                                            : spdlog::level::info;
      spdlog::log(level, "call={} method={} status={} ms={:.1f} peer={}", id_, LogSafe(method),
                  StatusName(status.error_code()), ms, LogSafe(info_->server_context()->peer()));
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  std::uint64_t id_ = 0;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

class CallLogFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  grpc::experimental::Interceptor* CreateServerInterceptor(grpc::experimental::ServerRpcInfo* info) override {
    return new CallLog(info);
  }
};

}  // namespace

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> CallLogInterceptors() {
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> factories;
  factories.push_back(std::make_unique<CallLogFactory>());
  return factories;
}

}  // namespace cinevol::service

// The access log: one line per call when it ends, in key=value form, with a
// request id that the caller also gets back (trailing metadata
// `cinevol-request-id`) to quote when reporting a problem:
//
//   call=42 method=SessionService/CreateSession status=RESOURCE_EXHAUSTED ms=0.8 peer=ipv4:127.0.0.1:50312
//
// A gRPC server interceptor, so every method is logged alike without each
// handler taking part. Sessions log their own events as "session <id>: ...".
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include <memory>
#include <vector>

namespace cinevol::service {

std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> CallLogInterceptors();

}  // namespace cinevol::service

// Server reflection (grpc.reflection.v1alpha: what `grpcurl list` and
// `grpcurl describe` ask), behind the same authentication as every cinevol
// call: where tokens or client certificates are required, reflection
// requires them too. It describes what this program's protobuf descriptors
// hold; it lists the services the server registered.
#pragma once

#include <string>
#include <vector>

#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "service/service_core.h"

namespace cinevol::service {

class ReflectionService final : public grpc::reflection::v1alpha::ServerReflection::CallbackService {
 public:
  // `services`: the full names ListServices answers (this one's is added).
  ReflectionService(ServiceCore* core, std::vector<std::string> services);

  grpc::ServerBidiReactor<grpc::reflection::v1alpha::ServerReflectionRequest,
                          grpc::reflection::v1alpha::ServerReflectionResponse>*
  ServerReflectionInfo(grpc::CallbackServerContext* context) override;

 private:
  ServiceCore* core_;
  std::vector<std::string> services_;
};

}  // namespace cinevol::service

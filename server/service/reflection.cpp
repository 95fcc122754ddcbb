// ReflectionService: one reactor per stream, a response to each request.
#include "service/reflection.h"

#include <fmt/format.h>
#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <set>

#include "grpc/health/v1/health.pb.h"
#include "runtime/errors.h"

namespace cinevol::service {
namespace {

namespace pb = google::protobuf;
using grpc::reflection::v1alpha::ServerReflectionRequest;
using grpc::reflection::v1alpha::ServerReflectionResponse;

// Reads a request, writes its answer, reads the next: one write in flight.
// A caller the server does not authenticate gets UNAUTHENTICATED and nothing else.
class ReflectionReactor final : public grpc::ServerBidiReactor<ServerReflectionRequest, ServerReflectionResponse> {
 public:
  ReflectionReactor(grpc::CallbackServerContext* context, ServiceCore* core, const std::vector<std::string>* services)
      : services_(services) {
    const grpc::Status status = Guarded([&] { core->Authenticate(*context); });
    if (!status.ok()) {
      Finish(status);
      return;
    }
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // the client is done asking
      Finish(grpc::Status::OK);
      return;
    }
    response_ = Answer(request_);
    StartWrite(&response_);
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(RpcError::Unavailable("the stream to the client broke").status());
      return;
    }
    StartRead(&request_);
  }

  void OnDone() override { delete this; }

 private:
  ServerReflectionResponse Answer(const ServerReflectionRequest& request) {
    ServerReflectionResponse response;
    response.set_valid_host(request.host());
    *response.mutable_original_request() = request;
    const pb::DescriptorPool& pool = *pb::DescriptorPool::generated_pool();
    auto fail = [&](const grpc::Status& status) {
      response.mutable_error_response()->set_error_code(int(status.error_code()));
      response.mutable_error_response()->set_error_message(status.error_message());
    };
    auto not_found = [&](const std::string& what) { fail(RpcError::NotFound(what).status()); };
    switch (request.message_request_case()) {
      case ServerReflectionRequest::kListServices:
        for (const std::string& name : *services_)
          response.mutable_list_services_response()->add_service()->set_name(name);
        break;
      case ServerReflectionRequest::kFileByFilename:
        if (const pb::FileDescriptor* file = pool.FindFileByName(request.file_by_filename())) {
          AddFiles(file, response);
        } else {
          not_found(fmt::format("no file '{}'", request.file_by_filename()));
        }
        break;
      case ServerReflectionRequest::kFileContainingSymbol:
        if (const pb::FileDescriptor* file = pool.FindFileContainingSymbol(request.file_containing_symbol())) {
          AddFiles(file, response);
        } else {
          not_found(fmt::format("no symbol '{}'", request.file_containing_symbol()));
        }
        break;
      case ServerReflectionRequest::kFileContainingExtension: {
        const auto& e = request.file_containing_extension();
        const pb::Descriptor* type = pool.FindMessageTypeByName(e.containing_type());
        const pb::FieldDescriptor* extension = type ? pool.FindExtensionByNumber(type, e.extension_number()) : nullptr;
        if (extension) {
          AddFiles(extension->file(), response);
        } else {
          not_found(fmt::format("no extension {} of '{}'", e.extension_number(), e.containing_type()));
        }
        break;
      }
      case ServerReflectionRequest::kAllExtensionNumbersOfType:
        if (const pb::Descriptor* type = pool.FindMessageTypeByName(request.all_extension_numbers_of_type())) {
          std::vector<const pb::FieldDescriptor*> extensions;
          pool.FindAllExtensions(type, &extensions);
          auto* numbers = response.mutable_all_extension_numbers_response();
          numbers->set_base_type_name(type->full_name());
          for (const pb::FieldDescriptor* f : extensions) numbers->add_extension_number(f->number());
        } else {
          not_found(fmt::format("no message type '{}'", request.all_extension_numbers_of_type()));
        }
        break;
      default:
        fail(RpcError::InvalidArgument("the request asks nothing (set one of its fields)").status());
        break;
    }
    return response;
  }

  // `file` itself, then what it imports (transitively) that this stream has not carried yet.
  void AddFiles(const pb::FileDescriptor* file, ServerReflectionResponse& response) {
    auto* files = response.mutable_file_descriptor_response();
    std::vector<const pb::FileDescriptor*> pending{file};
    std::set<const pb::FileDescriptor*> queued{file};
    while (!pending.empty()) {
      const pb::FileDescriptor* f = pending.back();
      pending.pop_back();
      pb::FileDescriptorProto proto;
      f->CopyTo(&proto);
      files->add_file_descriptor_proto(proto.SerializeAsString());
      sent_.insert(f);
      for (int i = 0; i < f->dependency_count(); ++i) {
        const pb::FileDescriptor* d = f->dependency(i);
        if (!sent_.count(d) && queued.insert(d).second) pending.push_back(d);
      }
    }
  }

  const std::vector<std::string>* services_;
  ServerReflectionRequest request_;
  ServerReflectionResponse response_;
  std::set<const pb::FileDescriptor*> sent_;  // files this stream carried
};

}  // namespace

ReflectionService::ReflectionService(ServiceCore* core, std::vector<std::string> services)
    : core_(core), services_(std::move(services)) {
  services_.emplace_back(grpc::reflection::v1alpha::ServerReflection::service_full_name());
  // Links the health service's descriptors in, so that it can be described too.
  (void)grpc::health::v1::HealthCheckRequest::descriptor();
}

grpc::ServerBidiReactor<ServerReflectionRequest, ServerReflectionResponse>* ReflectionService::ServerReflectionInfo(
    grpc::CallbackServerContext* context) {
  return new ReflectionReactor(context, core_, &services_);
}

}  // namespace cinevol::service

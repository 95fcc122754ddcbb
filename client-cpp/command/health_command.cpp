// `cinevol health --server ADDR [--service NAME]`: the standard gRPC health
// check, as Kubernetes gRPC probes and the images' HEALTHCHECK ask it. The
// server as a whole ("", liveness) serves until it drains; the session
// service ("cinevol.v1.SessionService", readiness) serves while the server
// has room for another session. Prints the status; exits 0 when SERVING, 1
// otherwise, 3 when the server cannot be reached.
#include <fmt/format.h>
#include <grpcpp/grpcpp.h>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace cinevol::cli {
namespace {

struct HealthOptions {
  ConnectionOptions connection;
  std::string service;
};

void Run(const HealthOptions& o) {
  const Client client = Connect(o.connection);
  auto stub = grpc::health::v1::Health::NewStub(client.channel());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::milliseconds(int(o.connection.connect_seconds * 1000)));
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(o.service);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, request, &response);
  if (!status.ok()) throw RpcError(status);
  fmt::print("{}\n", grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()));
  if (response.status() != grpc::health::v1::HealthCheckResponse::SERVING) throw CLI::RuntimeError(1);
}

}  // namespace

void AddHealthCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("health", "A server's gRPC health: SERVING (exit 0) or not (exit 1)");
  auto o = std::make_shared<HealthOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_option("--service", o->service,
                  "\"\" (default): the server is alive; cinevol.v1.SessionService: it has room for a session");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

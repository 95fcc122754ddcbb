// Capacity as a load balancer sees it (issue 23): the standard gRPC health
// service says the server is alive ("") and, for cinevol.v1.SessionService,
// whether another session fits; a full server refuses new sessions with
// RESOURCE_EXHAUSTED and its readiness turns NOT_SERVING until one ends.
#include <gtest/gtest.h>

#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;
using grpc::health::v1::HealthCheckResponse;

HealthCheckResponse::ServingStatus Health(Client& client, const std::string& service) {
  auto stub = grpc::health::v1::Health::NewStub(client.channel());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, request, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return response.status();
}

// Polls readiness until it reads `want` (the server updates it every 200 ms), 5 s at most.
bool ReadinessBecomes(Client& client, HealthCheckResponse::ServingStatus want) {
  for (int i = 0; i < 50; ++i) {
    if (Health(client, "cinevol.v1.SessionService") == want) return true;
    std::this_thread::sleep_for(100ms);
  }
  return false;
}

TEST(Capacity, AFullServerRefusesSessionsAndIsNotReadyUntilOneEnds) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-sessions", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  EXPECT_EQ(Health(client, ""), HealthCheckResponse::SERVING);
  EXPECT_TRUE(ReadinessBecomes(client, HealthCheckResponse::SERVING));

  const auto created = client.CreateSession(SmallSession());
  EXPECT_TRUE(ReadinessBecomes(client, HealthCheckResponse::NOT_SERVING)) << "full, yet ready";
  EXPECT_EQ(Health(client, ""), HealthCheckResponse::SERVING) << "full is not dead";
  ExpectRpcError([&] { client.CreateSession(SmallSession()); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-sessions");
  const auto [code, out] = RunProgram(CliPath(), {"health", "--server", server.address(), "--service",
                                                  "cinevol.v1.SessionService"},
                                      scratch / "health.log", 30s);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("NOT_SERVING"), std::string::npos) << out;

  client.CloseSession(created.session_id());
  EXPECT_TRUE(ReadinessBecomes(client, HealthCheckResponse::SERVING)) << "room again, yet not ready";
}

}  // namespace
}  // namespace cinevol::testing

// cinevol-server as a program: probes (gRPC health checking, reflection),
// settings from a config file, clear refusals of bad flags, and an orderly
// stop on SIGTERM with a stream open.
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include <future>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

std::string ToString(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  buffer.Dump(&slices);
  std::string s;
  for (const grpc::Slice& slice : slices) s.append(reinterpret_cast<const char*>(slice.begin()), slice.size());
  return s;
}

grpc::ByteBuffer ToBuffer(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

TEST(CinevolServer, AnswersHealthChecksAndReflection) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  grpc::GenericStub stub(client.channel());

  // grpc.health.v1.Health/Check for the whole server: HealthCheckRequest{} is
  // empty; HealthCheckResponse{status: SERVING} is field 1 = 1.
  grpc::ClientContext health_context;
  health_context.set_deadline(std::chrono::system_clock::now() + 10s);
  const grpc::ByteBuffer request = ToBuffer("");
  grpc::ByteBuffer response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&health_context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status s) { done.set_value(s); });
  const grpc::Status health = done.get_future().get();
  ASSERT_TRUE(health.ok()) << health.error_message();
  EXPECT_EQ(ToString(response), std::string("\x08\x01", 2));

  // Reflection lists the services: ServerReflectionRequest{list_services: ""} is field 7.
  grpc::ClientContext reflection_context;
  reflection_context.set_deadline(std::chrono::system_clock::now() + 10s);
  grpc::CompletionQueue cq;
  auto call = stub.PrepareCall(&reflection_context, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                               &cq);
  void* tag = nullptr;
  bool ok = false;
  call->StartCall(reinterpret_cast<void*>(1));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  call->Write(ToBuffer(std::string("\x3a\x00", 2)), reinterpret_cast<void*>(2));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  grpc::ByteBuffer listing;
  call->Read(&listing, reinterpret_cast<void*>(3));
  ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
  const std::string services = ToString(listing);
  for (const char* name : {"cinevol.v1.SessionService", "cinevol.v1.VolumeService", "cinevol.v1.ServerService",
                           "grpc.health.v1.Health"}) {
    EXPECT_NE(services.find(name), std::string::npos) << name;
  }
  reflection_context.TryCancel();
  grpc::Status finished;
  call->Finish(&finished, reinterpret_cast<void*>(4));
  cq.Next(&tag, &ok);
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
}

TEST(CinevolServer, ReadsItsSettingsFromAConfigFile) {
  ScratchDir scratch;
  std::ofstream(scratch / "server.toml") << "max-sessions = 1\nmax-pixels = 20000\n";
  ServerProcess server(scratch.path(), {"--config", (scratch / "server.toml").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  client.CreateSession(SmallSession());
  try {
    client.CreateSession(SmallSession());
    ADD_FAILURE() << "a second session beyond max-sessions = 1";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(std::string(e.what()).find("--max-sessions"), std::string::npos) << e.what();
  }
}

std::pair<int, std::string> RunServer(const ScratchDir& scratch, const std::vector<std::string>& args) {
  return RunProgram(ServerPath(), args, scratch / "refused.log", std::chrono::seconds(60));
}

TEST(CinevolServer, RefusesBadSettingsWithAMessage) {
  ScratchDir scratch;
  const std::vector<std::string> small{"--volume", "phantom:cube?size=8", "--backend", "cpu"};
  auto with = [&](std::vector<std::string> extra) {
    extra.insert(extra.end(), small.begin(), small.end());
    return extra;
  };
  auto [code, out] = RunServer(scratch, with({"--listen", "not an address"}));
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--listen"), std::string::npos) << out;
  std::tie(code, out) = RunServer(scratch, with({"--data-root", (scratch / "missing").string()}));
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--data-root"), std::string::npos) << out;
  std::tie(code, out) = RunServer(scratch, {"--volume", (scratch / "missing.nii").string(), "--backend", "cpu"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("missing.nii"), std::string::npos) << out;
  std::tie(code, out) = RunServer(scratch, with({"--backend", "gpu"}));
  EXPECT_NE(code, 0) << out;
  EXPECT_NE(out.find("--backend"), std::string::npos) << out;
  std::tie(code, out) = RunServer(scratch, with({"--advertise-address", "pod-0 :50051"}));
  EXPECT_NE(code, 0) << out;
  EXPECT_NE(out.find("--advertise-address"), std::string::npos) << out;
  EXPECT_NE(out.find("HOST:PORT"), std::string::npos) << out;
  std::tie(code, out) = RunServer(scratch, {"--help"});
  EXPECT_EQ(code, 0);
  for (const char* flag : {"--listen", "--backend", "--devices", "--data-root", "--config"}) {
    EXPECT_NE(out.find(flag), std::string::npos) << flag;
  }
}

// On the CPU backend nvJPEG cannot run, library or not (CI has neither a GPU
// nor libnvjpeg: there the message names the missing library), nor can the
// GPU's own coder.
TEST(CinevolServer, RefusesNvjpegWhereItCannotRunNamingWhy) {
  ScratchDir scratch;
  auto [code, out] =
      RunServer(scratch, {"--jpeg-encoder", "nvjpeg", "--volume", "phantom:cube?size=8", "--backend", "cpu"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--jpeg-encoder nvjpeg: "), std::string::npos) << out;
  const bool named = out.find("libnvjpeg not found") != std::string::npos ||
                     out.find("frames render on the CPU") != std::string::npos;
  EXPECT_TRUE(named) << out;
  std::tie(code, out) = RunServer(scratch, {"--jpeg-encoder", "gpu", "--backend", "cpu"});
  EXPECT_NE(code, 0) << out;
  EXPECT_NE(out.find("--jpeg-encoder"), std::string::npos) << out;
  // The GPU's own coder needs frames rendered on a GPU too.
  std::tie(code, out) =
      RunServer(scratch, {"--jpeg-encoder", "cuda", "--volume", "phantom:cube?size=8", "--backend", "cpu"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--jpeg-encoder cuda: frames render on the CPU"), std::string::npos) << out;
}

TEST(CinevolServer, StopsInOrderOnSigtermWithAStreamOpen) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  StreamOptions no_resume;
  no_resume.resume = false;  // the server is going away for good
  auto stream = client.Attach(created.session_id(), no_resume);
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }));
  const int status = server.Stop();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "wait status " << status;
  EXPECT_TRUE(Eventually([&] { return stream->ended(); }, 10s));
  EXPECT_FALSE(stream->status().ok());
}

}  // namespace
}  // namespace cinevol::testing

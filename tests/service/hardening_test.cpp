// The attacks that broke the first cinevol-server, each against a real
// server on loopback: uploads that name other files, FIFOs, descriptor
// exhaustion, other principals' sessions and volumes, requests past every
// limit, quiet calls, expensive frames and abandoned stills, SIGTERM with
// work in flight, forged log lines, event floods and crowds.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <atomic>
#include <fstream>
#include <regex>
#include <thread>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using Seconds = std::chrono::duration<double>;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return Seconds(std::chrono::steady_clock::now() - start).count();
}

void WriteFile(const std::filesystem::path& path, const std::string& text) { std::ofstream(path) << text; }

Client Connect(const ServerProcess& server, const std::string& token = {}, int call_seconds = 60) {
  ClientOptions options;
  options.address = server.address();
  options.token = token;
  options.call_timeout = std::chrono::seconds(call_seconds);
  return Client(options);
}

TEST(Hardening, UploadsThatNameAnotherFileAreRefused) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const std::string secret = (scratch / "secret.raw").string();
  WriteFile(secret, std::string(64, 'S'));

  WriteFile(scratch / "detached.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"
                                       "byte skip: 3\ndata file: " + secret + "\n\n");
  WriteFile(scratch / "detached.mha", "ObjectType = Image\nNDims = 3\nDimSize = 1 1 1\nElementType = MET_UCHAR\n"
                                      "HeaderSize = 3\nElementDataFile = " + secret + "\n");
  for (const char* name : {"detached.nrrd", "detached.mha"}) {
    try {
      client.UploadVolume(scratch / name);
      ADD_FAILURE() << name << " was loaded: it reads " << secret;
    } catch (const RpcError& e) {
      EXPECT_EQ(e.code(), grpc::StatusCode::INVALID_ARGUMENT) << e.what();
      EXPECT_NE(std::string(e.what()).find("self-contained"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(std::string("upload:") + name), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find(scratch.path().string()), std::string::npos)
          << "a server path: " << e.what();
    }
  }
  ExpectServing(client);
}

TEST(Hardening, FifosAreRefusedWithoutBlocking) {
  ScratchDir scratch;
  const auto root = scratch / "data";
  std::filesystem::create_directories(root);
  ASSERT_EQ(mkfifo((root / "volume.nrrd").c_str(), 0600), 0);
  ASSERT_EQ(mkfifo((root / "sky.exr").c_str(), 0600), 0);
  ServerProcess server(scratch.path(), {"--data-root", root.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = Connect(server, {}, 10);

  const auto start = std::chrono::steady_clock::now();
  ExpectRpcError([&] { client.LoadVolume("volume.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "not a regular file");
  v1::CreateSessionRequest r = SmallSession();
  v1::Scene* scene = r.mutable_scene();
  scene->mutable_transfer_function()->set_preset("ct-bone");
  scene->add_lights()->mutable_environment()->set_map("sky.exr");
  scene->mutable_lights(0)->mutable_environment()->set_intensity(1);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "lights[0].environment.map");
  EXPECT_LT(SecondsSince(start), 5.0);
  ExpectServing(client);
  EXPECT_EQ(server.Stop(), 0) << "a blocked loader would hold the shutdown";
}

// Opens `count` TCP connections to `port` that never speak; returns their descriptors.
std::vector<int> IdleConnections(int port, int count) {
  std::vector<int> fds;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  for (int i = 0; i < count; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) break;
    if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      close(fd);
      continue;
    }
    fds.push_back(fd);
  }
  return fds;
}

TEST(Hardening, TheListenerSurvivesDescriptorExhaustion) {
  ScratchDir scratch;
  // 256 descriptors in all: 600 idle connections would take every one.
  ServerProcess server(scratch.path(), {"--handshake-seconds", "2"}, "cpu", 256);
  ASSERT_TRUE(server.running()) << server.Log();
  for (int round = 0; round < 2; ++round) {
    std::vector<int> idle = IdleConnections(server.port(), 600);
    EXPECT_GT(idle.size(), 300u);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    for (int fd : idle) close(fd);
    EXPECT_TRUE(Eventually(
        [&] {
          try {
            Connect(server, {}, 10).ListVolumes();
            return true;
          } catch (const RpcError&) {
            return false;
          }
        },
        std::chrono::seconds(15)))
        << "round " << round << ": the server no longer accepts connections\n"
        << server.Log();
  }
  Client client = Connect(server);
  ExpectServing(client);
}

TEST(Hardening, SessionsAndUploadsBelongToTheirPrincipal) {
  ScratchDir scratch;
  WriteFile(scratch / "tokens", "alice-token alice\nbob-token bob\nroot-token root operator\n");
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client alice = server.Connect("alice-token"), bob = server.Connect("bob-token"), root = server.Connect("root-token");

  const auto a1 = alice.CreateSession(SmallSession()), a2 = alice.CreateSession(SmallSession());
  EXPECT_TRUE(std::regex_match(a1.session_id(), std::regex("[0-9a-f]{32}"))) << a1.session_id();
  EXPECT_NE(a1.session_id(), a2.session_id());
  const auto b1 = bob.CreateSession(SmallSession());
  EXPECT_FALSE(FindSessionStatus(bob, a1.session_id())) << "bob sees alice's session";
  EXPECT_TRUE(FindSessionStatus(bob, b1.session_id()));
  EXPECT_EQ(bob.Status().sessions_size(), 1);
  EXPECT_EQ(root.Status().sessions_size(), 3) << "the operator sees every session";
  ExpectRpcError([&] { bob.CloseSession(a1.session_id()); }, grpc::StatusCode::PERMISSION_DENIED, "another user");
  v1::SnapshotRequest still;
  still.set_session_id(a1.session_id());
  still.set_spp(1);
  ExpectRpcError([&] { bob.Snapshot(still); }, grpc::StatusCode::PERMISSION_DENIED, "another user");
  EXPECT_EQ(root.Snapshot(still).spp(), 1u) << "the operator may";

  // Uploads are their uploader's alone; the operator's volumes, the operator's.
  WriteSmallNrrd(scratch / "private.nrrd");
  const v1::VolumeInfo upload = alice.UploadVolume(scratch / "private.nrrd");
  for (const v1::VolumeInfo& v : bob.ListVolumes()) EXPECT_NE(v.id(), upload.id()) << "bob lists alice's upload";
  ExpectRpcError([&] { bob.DescribeVolume(upload.id()); }, grpc::StatusCode::PERMISSION_DENIED, "another user");
  ExpectRpcError([&] { bob.UnloadVolume(upload.id()); }, grpc::StatusCode::PERMISSION_DENIED, "another user");
  v1::CreateSessionRequest on_upload = SmallSession();
  on_upload.set_volume_id(upload.id());
  ExpectRpcError([&] { bob.CreateSession(on_upload); }, grpc::StatusCode::PERMISSION_DENIED, "another user");
  ExpectRpcError([&] { bob.UnloadVolume("phantom:head?size=48"); }, grpc::StatusCode::PERMISSION_DENIED,
                 "the operator");
  ExpectRpcError([&] { alice.UnloadVolume("phantom:head?size=48"); }, grpc::StatusCode::PERMISSION_DENIED,
                 "the operator");
  alice.UnloadVolume(upload.id());
  for (const auto& id : {a1.session_id(), a2.session_id()}) alice.CloseSession(id);
  bob.CloseSession(b1.session_id());
  EXPECT_TRUE(Eventually([&] { return root.DescribeVolume("phantom:head?size=48").sessions() == 0; },
                         std::chrono::seconds(10)));
  root.UnloadVolume("phantom:head?size=48");
}

TEST(Hardening, EveryLimitIsEnforcedAndNamed) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(),
                       {"--max-lights", "2", "--max-tf-points", "4", "--max-bounces", "8", "--max-frame-samples",
                        "40000", "--max-sessions-per-principal", "2", "--max-total-pixels", "15000",
                        "--max-snapshot-samples", "100000", "--max-volume-voxels", "1000", "--max-upload-mb", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();

  auto scene_request = [] {
    v1::CreateSessionRequest r = SmallSession();
    r.mutable_scene()->mutable_transfer_function()->set_preset("ct-bone");
    return r;
  };
  v1::CreateSessionRequest r = scene_request();
  for (int i = 0; i < 3; ++i) r.mutable_scene()->add_lights()->mutable_point()->set_intensity(1);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-lights");
  r = scene_request();
  for (int i = 0; i < 5; ++i) r.mutable_scene()->mutable_transfer_function()->add_points()->set_value(float(i));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-tf-points");
  r = scene_request();  // a label's own transfer function is bounded the same way
  auto* own = r.mutable_scene()->mutable_labels()->add_styles()->mutable_transfer_function();
  for (int i = 0; i < 5; ++i) own->add_points()->set_value(float(i));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "labels.styles[0].transfer_function.points");
  r = scene_request();
  r.mutable_scene()->mutable_render()->set_max_bounces(9);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-bounces");
  r = scene_request();
  r.mutable_scene()->mutable_render()->set_spp(8);  // 96 x 64 x 8 samples
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-frame-samples");
  ExpectRpcError([&] { client.CreateSession(SmallSession("ct-bone", 150, 101)); },
                 grpc::StatusCode::RESOURCE_EXHAUSTED, "--max-total-pixels");

  const auto first = client.CreateSession(SmallSession("ct-bone", 64, 64));
  const auto second = client.CreateSession(SmallSession("ct-bone", 64, 64));
  ExpectRpcError([&] { client.CreateSession(SmallSession("ct-bone", 8, 8)); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-sessions-per-principal");
  v1::SnapshotRequest still;
  still.set_session_id(first.session_id());
  still.set_spp(64);  // 64 x 64 x 64 samples
  ExpectRpcError([&] { client.Snapshot(still); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-snapshot-samples");
  // A resize past the pixel budget ends the session that asked, and only it.
  auto stream = client.Attach(second.session_id());
  v1::SessionEvent resize;
  resize.mutable_resize()->set_width(120);
  resize.mutable_resize()->set_height(100);
  stream->Send(resize);
  EXPECT_TRUE(Eventually([&] { return stream->ended(); }, std::chrono::seconds(10)));
  EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(stream->status().error_message().find("--max-total-pixels"), std::string::npos);
  client.CloseSession(first.session_id());

  WriteSmallNrrd(scratch / "big.nrrd");  // 16^3 voxels, over 1000
  ExpectRpcError([&] { client.UploadVolume(scratch / "big.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "upload:big.nrrd");

  // One message may not make the server parse megabytes.
  r = scene_request();
  r.mutable_scene()->mutable_transfer_function()->set_preset(std::string(2 << 20, 'x'));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::RESOURCE_EXHAUSTED, "larger than max");
  ExpectServing(client);
}

// A 64 x 64 x 120 volume of 16-bit values: just under 1 MiB once loaded
// (voxels, their block ranges and the histogram).
void WriteMegabyteNrrd(const std::filesystem::path& path) {
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: short\ndimension: 3\nsizes: 64 64 120\nspacings: 1 1 1\nencoding: raw\nendian: little\n\n";
  std::vector<std::int16_t> voxels(64 * 64 * 120);
  for (std::size_t i = 0; i < voxels.size(); ++i) voxels[i] = std::int16_t(int(i % 2000) - 1000);
  out.write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * sizeof(std::int16_t)));
}

TEST(Hardening, VolumeMemoryIsBounded) {
  ScratchDir scratch;
  WriteFile(scratch / "tokens", "alice-token alice\nbob-token bob\n");
  WriteMegabyteNrrd(scratch / "mega.nrrd");
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string(), "--max-upload-memory-mb",
                                        "1", "--max-volume-memory-mb", "2"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client alice = server.Connect("alice-token"), bob = server.Connect("bob-token");
  alice.UploadVolume(scratch / "mega.nrrd");
  ExpectRpcError([&] { alice.UploadVolume(scratch / "mega.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-upload-memory-mb");
  ExpectRpcError([&] { bob.UploadVolume(scratch / "mega.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-volume-memory-mb");
}

// A raw upload call, for uploads that stop half way.
class RawUpload {
 public:
  explicit RawUpload(Client& client, const std::string& name = "stalled.nrrd", std::uint64_t size = 1000)
      : stub_(v1::VolumeService::NewStub(client.channel())) {
    context_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    writer_ = stub_->UploadVolume(&context_, &info_);
    v1::UploadVolumeChunk header;
    header.mutable_header()->set_file_name(name);
    header.mutable_header()->set_size_bytes(size);
    writer_->Write(header);
  }
  bool Send(const std::string& bytes) {
    v1::UploadVolumeChunk chunk;
    chunk.set_data(bytes);
    return writer_->Write(chunk);
  }
  grpc::Status Finish() {
    writer_->WritesDone();
    return writer_->Finish();
  }
  // Sends nothing more and waits for the server to end the call.
  grpc::Status Wait() { return writer_->Finish(); }
  void Cancel() { context_.TryCancel(); }

 private:
  std::unique_ptr<v1::VolumeService::Stub> stub_;
  grpc::ClientContext context_;
  v1::VolumeInfo info_;
  std::unique_ptr<grpc::ClientWriter<v1::UploadVolumeChunk>> writer_;
};

TEST(Hardening, QuietCallsAndSessionsExpire) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--first-message-seconds", "1", "--upload-idle-seconds", "1",
                                        "--unattached-session-seconds", "1", "--max-uploads-per-principal", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();

  // A stream that never attaches.
  auto stub = v1::SessionService::NewStub(client.channel());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
  const auto start = std::chrono::steady_clock::now();
  auto silent = stub->StreamSession(&context);
  v1::ServerMessage message;
  while (silent->Read(&message)) {
  }
  EXPECT_EQ(silent->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_LT(SecondsSince(start), 5.0) << "--first-message-seconds 1";

  // An upload that stops sending holds the caller's one upload slot until it ends.
  {
    RawUpload stalled(client);
    EXPECT_TRUE(stalled.Send("NRRD"));
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    WriteSmallNrrd(scratch / "second.nrrd");
    ExpectRpcError([&] { client.UploadVolume(scratch / "second.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                   "--max-uploads-per-principal");
    const auto upload_start = std::chrono::steady_clock::now();
    const grpc::Status status = stalled.Wait();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED) << status.error_message();
    EXPECT_LT(SecondsSince(upload_start), 5.0) << "--upload-idle-seconds 1";
  }
  EXPECT_TRUE(Eventually(
      [&] {
        try {
          client.UploadVolume(scratch / "second.nrrd");
          return true;
        } catch (const RpcError&) {
          return false;
        }
      },
      std::chrono::seconds(5)))
      << "the slot came back";

  // A session nobody attaches to.
  const auto created = client.CreateSession(SmallSession());
  EXPECT_TRUE(Eventually([&] { return !FindSessionStatus(client, created.session_id()); }, std::chrono::seconds(5)));
}

TEST(Hardening, AnExpensiveFrameStopsWhenItsSessionCloses) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-bounces", "256", "--max-frame-samples", "100000000"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  // A white, dense, purely scattering box: every path takes all its 256
  // bounces. 640x480 at 256 samples a pixel: seconds even on 16 cores.
  v1::CreateSessionRequest heavy = SmallSession("ct-bone", 640, 480);
  v1::Scene* scene = heavy.mutable_scene();
  for (float value : {-5000.0f, 5000.0f}) {
    v1::TransferFunctionPoint* p = scene->mutable_transfer_function()->add_points();
    p->set_value(value);
    p->set_opacity(1);
    p->mutable_diffuse()->set_r(1);
    p->mutable_diffuse()->set_g(1);
    p->mutable_diffuse()->set_b(1);
  }
  scene->mutable_transfer_function()->set_gradient_factor(0);
  scene->mutable_render()->set_spp(256);
  scene->mutable_render()->set_max_bounces(256);
  const auto expensive = client.CreateSession(heavy);
  auto stream = client.Attach(expensive.session_id());
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // its first frame is under way (seconds of work)
  EXPECT_FALSE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, std::chrono::milliseconds(1)))
      << "the frame was too cheap to test cancellation";

  const auto start = std::chrono::steady_clock::now();
  client.CloseSession(expensive.session_id());
  const auto cheap = client.CreateSession(SmallSession());
  auto next = client.Attach(cheap.session_id());
  EXPECT_TRUE(WaitFrame(*next, [](const v1::Frame& f) { return f.frame_id() >= 1; }, std::chrono::seconds(30)));
  EXPECT_LT(SecondsSince(start), 3.0) << "the closed session's frame held the worker";
}

TEST(Hardening, AnAbandonedSnapshotStopsRendering) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client impatient = Connect(server);
  const auto created = impatient.CreateSession(SmallSession());
  v1::SnapshotRequest still;
  still.set_session_id(created.session_id());
  still.set_spp(16384);  // minutes on a CPU
  SnapshotOptions one_second;
  one_second.timeout = std::chrono::seconds(1);
  ExpectRpcError([&] { impatient.Snapshot(still, one_second); }, grpc::StatusCode::DEADLINE_EXCEEDED, "timeout");

  Client client = server.Connect();
  const auto start = std::chrono::steady_clock::now();
  const auto other = client.CreateSession(SmallSession());
  auto stream = client.Attach(other.session_id());
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, std::chrono::seconds(30)));
  EXPECT_LT(SecondsSince(start), 3.0) << "the abandoned snapshot still renders";

  // Closing the session cancels its snapshot too.
  std::atomic<int> code{-1};
  std::string message;  // read once `code` is set
  std::thread waiting([&] {
    try {
      client.Snapshot(still);
      code = 0;
    } catch (const RpcError& e) {
      message = e.what();
      code = int(e.code());
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  client.CloseSession(created.session_id());
  EXPECT_TRUE(Eventually([&] { return code >= 0; }, std::chrono::seconds(5)));
  waiting.join();
  EXPECT_EQ(code, int(grpc::StatusCode::CANCELLED));
  EXPECT_NE(message.find("its session '" + created.session_id() + "' ended: it was closed"), std::string::npos)
      << "the message says why: " << message;
}

TEST(Hardening, SigtermDrainsWhateverIsInFlight) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--drain-seconds", "3"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto created = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  StreamOptions no_resume;
  no_resume.resume = false;
  auto stream = client.Attach(created.session_id(), no_resume);
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }));
  const auto still_session = client.CreateSession(SmallSession());
  std::atomic<int> still_code{-1};
  std::thread still([&] {
    v1::SnapshotRequest r;
    r.set_session_id(still_session.session_id());
    r.set_spp(16384);
    try {
      client.Snapshot(r);
      still_code = 0;
    } catch (const RpcError& e) {
      still_code = int(e.code());
    }
  });
  RawUpload upload(client);  // stays open: a load that never completes
  upload.Send("NRRD");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));

  const auto start = std::chrono::steady_clock::now();
  kill(server.pid(), SIGTERM);
  const int status = WaitExit(server.pid(), std::chrono::seconds(10));
  const double took = SecondsSince(start);
  ASSERT_NE(status, -1) << "still running 10 s after SIGTERM";
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  EXPECT_LT(took, 3.0 + 1.0) << "--drain-seconds 3";

  bool noticed = false;
  while (auto m = stream->Next(std::chrono::seconds(2))) {
    if (m->has_notice() && m->notice().message().find("shutting down") != std::string::npos) noticed = true;
  }
  EXPECT_TRUE(noticed) << "no draining notice on the stream";
  EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::UNAVAILABLE) << stream->status().error_message();
  still.join();
  EXPECT_NE(still_code, 0) << "the snapshot finished instead of being cancelled";
  upload.Cancel();
}

TEST(Hardening, ClientStringsCannotForgeLogLines) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const std::string forged = "x\n[2001-01-01 00:00:00.000] [info] forged line\n.nrrd";
  WriteSmallNrrd(scratch / "small.nrrd");
  {
    RawUpload upload(client, forged, std::filesystem::file_size(scratch / "small.nrrd"));
    std::ifstream in(scratch / "small.nrrd", std::ios::binary);
    upload.Send({std::istreambuf_iterator<char>(in), {}});
    upload.Finish();
  }
  v1::CreateSessionRequest r = SmallSession();
  r.set_volume_id("evil\n[2001-01-01 00:00:00.000] [info] forged line");
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::NOT_FOUND, "evil");
  ExpectServing(client);
  server.Stop();
  const std::string log = server.Log();
  EXPECT_EQ(log.find("\n[2001-01-01"), std::string::npos) << log;
}

TEST(Hardening, AnEventFloodCostsItsNeighbourLittle) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto neighbour = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  const auto noisy = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  auto watched = client.Attach(neighbour.session_id());
  ASSERT_TRUE(WaitFrame(*watched, [](const v1::Frame&) { return true; }));

  // The flooder: a raw stream whose writes gRPC may batch (buffer_hint), as
  // cheap for this process as a flood can be: the machine is shared.
  auto stub = v1::SessionService::NewStub(client.channel());
  grpc::ClientContext context;
  auto flood = stub->StreamSession(&context);
  v1::ClientMessage attach;
  attach.mutable_attach()->set_session_id(noisy.session_id());
  ASSERT_TRUE(flood->Write(attach));
  std::thread drain([&] {
    v1::ServerMessage m;
    while (flood->Read(&m)) {
    }
  });
  std::uint64_t seq = 0;
  auto measure = [&](int events_per_second) {
    std::atomic<bool> stop{false};
    std::thread sender([&] {
      const auto start = std::chrono::steady_clock::now();
      for (int i = 0; !stop && i < 20000; ++i) {
        v1::ClientMessage m;
        *m.mutable_event() = Orbit(i);
        m.mutable_event()->set_seq(++seq);
        flood->Write(m, grpc::WriteOptions().set_buffer_hint());
        if (i % 64 == 0) {
          std::this_thread::sleep_until(start + std::chrono::microseconds(i * 1000000ll / events_per_second));
        }
      }
    });
    const double fps = ReadingFps(*watched, std::chrono::seconds(2));
    stop = true;
    sender.join();
    return fps;
  };
  // Alternated, so that whatever else loads the machine weighs on both alike.
  double calm = 0, flooded = 0;
  for (int round = 0; round < 2; ++round) {
    calm += measure(60) / 2;
    flooded += measure(10000) / 2;
  }
  // A starved neighbour would read near 0; what the flood costs exactly is
  // the benchmarks' business (the CI machine is shared and noisy).
  EXPECT_GE(flooded, 0.5 * calm) << "calm " << calm << " fps, flooded " << flooded << " fps";
  EXPECT_LT(server.ResidentMiB(), 1024.0);
  const auto status = FindSessionStatus(client, noisy.session_id());
  ASSERT_TRUE(status) << "the flooding session ended";
  EXPECT_GT(status->frames_rendered(), 0u);
  context.TryCancel();
  drain.join();
}

TEST(Hardening, ACrowdPastTheSessionLimitLocksNobodyOut) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-sessions", "20", "--max-sessions-per-principal", "100",
                                        "--unattached-session-seconds", "5"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto mine = client.CreateSession(SmallSession("ct-bone", 96, 64, 65536));
  auto stream = client.Attach(mine.session_id());
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }));
  const double alone = ReadingFps(*stream, std::chrono::seconds(3));

  std::atomic<int> created{0}, refused{0};
  std::vector<std::thread> crowd;
  for (int i = 0; i < 100; ++i) {
    crowd.emplace_back([&] {
      try {
        Client c = Connect(server, {}, 10);
        c.CreateSession(SmallSession("ct-bone", 32, 32));  // and never attach
        ++created;
      } catch (const RpcError& e) {
        if (e.code() == grpc::StatusCode::RESOURCE_EXHAUSTED) ++refused;
      }
    });
  }
  for (auto& t : crowd) t.join();
  EXPECT_EQ(created, 19);
  EXPECT_EQ(refused, 81);
  // The crowd's sessions cost nothing until attached: no frame, no device
  // memory. That is the guarantee; the frame rate below only shows the
  // stream still flows (its exact value is a benchmark's business, and the
  // CI machine is shared).
  const auto status = client.Status();
  EXPECT_LE(status.sessions_size(), 20);
  for (const auto& s : status.sessions()) {
    if (s.session_id() == mine.session_id()) continue;
    EXPECT_EQ(s.frames_rendered(), 0u) << s.session_id();
    EXPECT_FALSE(s.holds_device_memory()) << s.session_id();
  }
  const double crowded = ReadingFps(*stream, std::chrono::seconds(3));
  EXPECT_GE(crowded, 0.5 * alone) << "alone " << alone << " fps, with the crowd " << crowded;
  EXPECT_LT(server.ResidentMiB(), 1024.0);
  // Sessions never attached expire, and the slots come back.
  EXPECT_TRUE(Eventually(
      [&] {
        try {
          client.CloseSession(client.CreateSession(SmallSession()).session_id());
          return true;
        } catch (const RpcError&) {
          return false;
        }
      },
      std::chrono::seconds(15)));
}

}  // namespace
}  // namespace cinevol::testing

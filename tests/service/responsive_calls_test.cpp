// Calls whose work grows with a volume run on the server's pools, never on
// gRPC's threads: while clients create sessions on a large labelled volume
// (each creation frames its view over every label voxel), another client's
// GetStatus and health are answered at once; a caller that goes away before
// its creation's turn leaves no session; a drain answers the creations still
// queued. Real servers on loopback; every wait is bounded.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <mutex>
#include <thread>
#include <vector>

#include "grpc/health/v1/health.grpc.pb.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// A ball of 1040 (a bony shell of 2400) in 0, n^3 voxels of 1 mm, as
// volume.nrrd, and labels.nrrd: the ball in eight labelled octants.
void WriteLabelledVolume(const fs::path& dir, int n) {
  const float c = 0.5f * float(n), r = 0.45f * float(n);
  auto write = [&](const fs::path& file, auto value) {
    std::ofstream out(file, std::ios::binary);
    out << "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: " << n << " " << n << " " << n
        << "\nspacings: 1 1 1\nencoding: raw\nendian: little\n\n";
    std::vector<std::uint16_t> row(n);
    for (int z = 0; z < n; ++z) {
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const float dx = float(x) + 0.5f - c, dy = float(y) + 0.5f - c, dz = float(z) + 0.5f - c;
          row[x] = value(x, y, z, std::sqrt(dx * dx + dy * dy + dz * dz));
        }
        out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size() * 2));
      }
    }
  };
  write(dir / "volume.nrrd", [&](int, int, int, float d) -> std::uint16_t {
    return d > r ? 0 : d > 0.9f * r ? 2400 : 1040;
  });
  write(dir / "labels.nrrd", [&](int x, int y, int z, float d) -> std::uint16_t {
    return d > r ? 0 : std::uint16_t(1 + x * 2 / n + 2 * (y * 2 / n) + 4 * (z * 2 / n));
  });
}

// A server on a labelled volume of n^3 voxels (its id in volume_id).
struct LabelledServer {
  LabelledServer(const ScratchDir& scratch, int n, std::vector<std::string> flags = {}) {
    WriteLabelledVolume(scratch.path(), n);
    flags.insert(flags.end(), {"--data-root", scratch.path().string(), "--max-sessions-per-principal", "64"});
    server = std::make_unique<ServerProcess>(scratch.path(), flags);
    if (!server->running()) return;
    Client setup = server->Connect();
    volume_id = setup.LoadVolume("volume.nrrd").id();
    setup.LoadLabels(volume_id, "labels.nrrd");
  }
  v1::CreateSessionRequest Request() const {
    v1::CreateSessionRequest r;  // the volume's default preset: a named view, framed over the labels
    r.set_volume_id(volume_id);
    r.mutable_viewport()->set_width(96);
    r.mutable_viewport()->set_height(64);
    return r;
  }
  std::unique_ptr<ServerProcess> server;
  std::string volume_id;
};

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

grpc::Status CheckHealth(grpc::health::v1::Health::Stub& stub) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 30s);
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  return stub.Check(&context, request, &response);
}

TEST(ResponsiveCalls, StatusAndHealthAnswerWhileFourClientsCreateLabelledSessions) {
  ScratchDir scratch;
  // 384^3: one labelled creation reads 56 million label voxels, about 1 s on
  // a small CPU; four at once kept gRPC's threads for seconds before.
  LabelledServer labelled(scratch, 384);
  ASSERT_TRUE(labelled.server && labelled.server->running()) << labelled.server->Log();
  ServerProcess& server = *labelled.server;
  const v1::CreateSessionRequest request = labelled.Request();

  // One creation alone: what the framing costs on this machine.
  Client first = server.Connect();
  Clock::time_point t0 = Clock::now();
  first.CloseSession(first.CreateSession(request).session_id());
  const double alone_ms = Ms(Clock::now() - t0);
  // Enough rounds that four clients keep the server's creation threads busy a few seconds.
  const int rounds = std::clamp(int(std::ceil(1500.0 / std::max(alone_ms, 1.0))), 1, 6);

  Client prober = server.Connect();
  auto health = grpc::health::v1::Health::NewStub(prober.channel());
  ASSERT_TRUE(CheckHealth(*health).ok());
  prober.Status();

  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 4; ++i) clients.push_back(std::make_unique<Client>(server.Connect()));
  std::mutex mu;
  std::vector<double> create_ms, status_ms, health_ms;
  std::atomic<int> failures{0}, running{4};
  const Clock::time_point give_up = Clock::now() + 300s;
  std::vector<std::thread> creators;
  const Clock::time_point begin = Clock::now();
  for (auto& client : clients) {
    creators.emplace_back([&, c = client.get()] {
      for (int i = 0; i < rounds && Clock::now() < give_up; ++i) {
        try {
          const Clock::time_point s = Clock::now();
          const std::string id = c->CreateSession(request).session_id();
          {
            std::lock_guard lock(mu);
            create_ms.push_back(Ms(Clock::now() - s));
          }
          c->CloseSession(id);
        } catch (const std::exception& e) {
          ++failures;
          ADD_FAILURE() << "CreateSession: " << e.what();
        }
      }
      --running;
    });
  }
  // A caller that gives up while its creation waits its turn.
  ClientOptions impatient_options;
  impatient_options.address = server.address();
  impatient_options.call_timeout = 100ms;
  Client impatient(impatient_options);
  std::this_thread::sleep_for(50ms);
  grpc::StatusCode impatient_code = grpc::StatusCode::OK;
  try {
    impatient.CloseSession(impatient.CreateSession(request).session_id());
  } catch (const RpcError& e) {
    impatient_code = e.code();
  }
  EXPECT_TRUE(impatient_code == grpc::StatusCode::OK || impatient_code == grpc::StatusCode::DEADLINE_EXCEEDED)
      << StatusCodeName(impatient_code);

  int status_failures = 0;
  while (running > 0 && Clock::now() < give_up) {
    const Clock::time_point s = Clock::now();
    try {
      prober.Status();
    } catch (const RpcError& e) {
      ++status_failures;
      ADD_FAILURE() << "GetStatus: " << e.what();
    }
    const Clock::time_point h = Clock::now();
    const grpc::Status checked = CheckHealth(*health);
    EXPECT_TRUE(checked.ok()) << checked.error_message();
    const Clock::time_point e = Clock::now();
    if (running > 0) {  // only what was answered while creations were under way
      status_ms.push_back(Ms(h - s));
      health_ms.push_back(Ms(e - h));
    }
    std::this_thread::sleep_for(20ms);
  }
  for (std::thread& t : creators) t.join();
  const double creating_ms = Ms(Clock::now() - begin);
  ASSERT_EQ(failures, 0);
  ASSERT_EQ(status_failures, 0);
  ASSERT_GE(status_ms.size(), 3u) << "too few probes while " << 4 * rounds << " creations ran for " << creating_ms
                                  << " ms";
  const double status_max = *std::max_element(status_ms.begin(), status_ms.end());
  const double health_max = *std::max_element(health_ms.begin(), health_ms.end());
  const std::string summary =
      "one creation alone " + std::to_string(alone_ms) + " ms; " + std::to_string(4 * rounds) +
      " creations by 4 clients: median " + std::to_string(Median(create_ms)) + " ms, " + std::to_string(creating_ms) +
      " ms in all; GetStatus median " + std::to_string(Median(status_ms)) + " max " + std::to_string(status_max) +
      " ms (" + std::to_string(status_ms.size()) + " calls); health median " + std::to_string(Median(health_ms)) +
      " max " + std::to_string(health_max) + " ms";
  std::printf("%s\n", summary.c_str());
  // Generous bounds (a shared CI machine): each answer within 2 s, and typically
  // far quicker than a creation, which is what a probe waited for before.
  EXPECT_LT(status_max, 2000.0) << summary;
  EXPECT_LT(health_max, 2000.0) << summary;
  EXPECT_LT(Median(status_ms), Median(create_ms) / 4) << summary;
  EXPECT_LT(Median(health_ms), Median(create_ms) / 4) << summary;

  // Whatever the impatient caller's creation did, it left no session behind
  // (every other session was closed).
  EXPECT_TRUE(Eventually([&] { return prober.Status().sessions_held() == 0; }, 10s))
      << prober.Status().sessions_held() << " sessions held; the impatient caller's got "
      << StatusCodeName(impatient_code);
}

TEST(ResponsiveCalls, ADrainAnswersCreationsStillQueued) {
  ScratchDir scratch;
  LabelledServer labelled(scratch, 256, {"--drain-seconds", "8"});
  ASSERT_TRUE(labelled.server && labelled.server->running()) << labelled.server->Log();
  ServerProcess& server = *labelled.server;
  const v1::CreateSessionRequest request = labelled.Request();

  // Twelve callers at once: two creations run, the others wait their turn,
  // a queue long enough (about six creations' time) that a SIGTERM sent
  // after 200 ms finds some still waiting even on 2 busy cores, where the
  // answers counted before it may be stale by the time the server drains
  // (eight callers once all ran before the drain under the full suite).
  constexpr int kCallers = 12;
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < kCallers; ++i) clients.push_back(std::make_unique<Client>(server.Connect()));
  std::mutex mu;
  std::vector<grpc::StatusCode> codes;
  std::vector<std::thread> callers;
  for (auto& client : clients) {
    callers.emplace_back([&, c = client.get()] {
      grpc::StatusCode code = grpc::StatusCode::OK;
      try {
        c->CreateSession(request);
      } catch (const RpcError& e) {
        code = e.code();
      }
      std::lock_guard lock(mu);
      codes.push_back(code);
    });
  }
  std::this_thread::sleep_for(200ms);
  std::size_t answered_before = 0;
  {
    std::lock_guard lock(mu);
    answered_before = codes.size();
  }
  const Clock::time_point term = Clock::now();
  const int status = server.Stop();  // SIGTERM, then up to 15 s
  const double exit_ms = Ms(Clock::now() - term);
  for (std::thread& t : callers) t.join();
  EXPECT_TRUE(status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0) << server.Log();
  EXPECT_LT(exit_ms, 8000.0 + 2000.0) << "past --drain-seconds\n" << server.Log();
  int refused = 0;
  for (grpc::StatusCode code : codes) {
    EXPECT_TRUE(code == grpc::StatusCode::OK || code == grpc::StatusCode::UNAVAILABLE ||
                code == grpc::StatusCode::CANCELLED)
        << StatusCodeName(code);
    refused += code != grpc::StatusCode::OK;
  }
  if (answered_before + 2 < std::size_t(kCallers)) {
    EXPECT_GT(refused, 0) << "creations still queued at SIGTERM ran anyway (" << answered_before
                          << " answered before it)";
  }
}

}  // namespace
}  // namespace cinevol::testing

// Stills on a CPU server (issue 32): a snapshot takes as long as its samples
// do, with no fixed deadline and without its session expiring under it; it
// reports progress; and when it does end early, the message says what ran
// out and what to do. The server's limits are shrunk to a second so that a
// still of a few seconds outlasts them.
#include <gtest/gtest.h>

#include <signal.h>

#include <atomic>
#include <thread>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

Client ClientOf(const ServerProcess& server, std::chrono::milliseconds call_timeout,
                std::chrono::milliseconds snapshot_silence = 120s) {
  ClientOptions options;
  options.address = server.address();
  options.call_timeout = call_timeout;
  options.snapshot_silence = snapshot_silence;
  return Client(options);
}

v1::SnapshotRequest StillOf(const std::string& session, int spp) {
  v1::SnapshotRequest still;
  still.set_session_id(session);
  still.set_spp(spp);
  return still;
}

double Seconds(std::chrono::steady_clock::duration d) { return std::chrono::duration<double>(d).count(); }

// The session is never attached (as `cinevol snapshot`'s own is), the server
// reaps such sessions after a second, and the client's unary calls give up
// after a second: the still takes about four and must come back whole.
TEST(Stills, ASnapshotLongerThanTheOldLimitsCompletes) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--unattached-session-seconds", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = ClientOf(server, 1s);
  const std::string session = client.CreateSession(SmallSession()).session_id();
  const int spp = SppForSeconds(client, session, 4.0);

  std::vector<v1::SnapshotProgress> progress;
  SnapshotOptions wait;
  wait.on_progress = [&](const v1::SnapshotProgress& p) { progress.push_back(p); };
  const auto start = std::chrono::steady_clock::now();
  v1::SnapshotResponse still;
  ASSERT_NO_THROW(still = client.Snapshot(StillOf(session, spp), wait)) << server.Log();
  EXPECT_GT(Seconds(std::chrono::steady_clock::now() - start), 1.5) << "not longer than the limits: " << spp << " spp";
  EXPECT_EQ(still.spp(), std::uint32_t(spp));
  EXPECT_EQ(DecodePng(std::vector<std::uint8_t>(still.image().begin(), still.image().end())).width, 96);

  // Progress: at once, well before the end, then growing, never past the
  // target. (The server says it accepted the still with nothing done, but
  // progress is newest-wins at both ends: a first step finished before the
  // client read that message replaces it.)
  ASSERT_GE(progress.size(), 2u);
  EXPECT_LT(progress.front().spp_done(), std::uint32_t(spp) / 2);
  for (std::size_t i = 1; i < progress.size(); ++i) {
    EXPECT_GE(progress[i].spp_done(), progress[i - 1].spp_done());
    EXPECT_LE(progress[i].spp_done(), std::uint32_t(spp));
    EXPECT_EQ(progress[i].spp(), std::uint32_t(spp));
  }
  EXPECT_GT(progress.back().spp_done(), 0u);

  // The still done, the session's second starts again: then it goes.
  EXPECT_TRUE(FindSessionStatus(client, session)) << "reaped as soon as the still ended";
  EXPECT_TRUE(Eventually([&] { return !FindSessionStatus(client, session); }, 10s)) << "never reaped";
}

TEST(Stills, ATimeoutSaysWhatRanOutAndWhatToDo) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = ClientOf(server, 60s);
  const std::string session = client.CreateSession(SmallSession()).session_id();
  SnapshotOptions wait;
  wait.timeout = 1s;
  const auto start = std::chrono::steady_clock::now();
  ExpectRpcError([&] { client.Snapshot(StillOf(session, 16384), wait); }, grpc::StatusCode::DEADLINE_EXCEEDED,
                 "did not finish within its timeout of 1 s");
  EXPECT_LT(Seconds(std::chrono::steady_clock::now() - start), 5.0);
  try {
    client.Snapshot(StillOf(session, 16384), wait);
  } catch (const RpcError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("of 16384 spp"), std::string::npos) << "how far it came: " << message;
    EXPECT_NE(message.find("allow more time, or ask for fewer samples per pixel or a smaller image"),
              std::string::npos)
        << "what to do: " << message;
  }
}

// A server that stops answering (here: stopped by a signal) is given up
// once it has reported nothing for the client's snapshot_silence.
TEST(Stills, ASnapshotWhoseServerFallsSilentIsGivenUp) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = ClientOf(server, 60s, 2s);
  const std::string session = client.CreateSession(SmallSession()).session_id();
  std::atomic<bool> started{false};
  SnapshotOptions wait;
  wait.on_progress = [&](const v1::SnapshotProgress&) { started = true; };
  std::thread stopper([&] {
    Eventually([&] { return started.load(); }, 30s);
    kill(server.pid(), SIGSTOP);
  });
  const auto start = std::chrono::steady_clock::now();
  ExpectRpcError([&] { client.Snapshot(StillOf(session, 16384), wait); }, grpc::StatusCode::DEADLINE_EXCEEDED,
                 "the server reported no progress on the snapshot for 2 s");
  stopper.join();
  kill(server.pid(), SIGCONT);
  EXPECT_LT(Seconds(std::chrono::steady_clock::now() - start), 20.0);
}

// The viewer's *Take snapshot*: a still of a session that is refining. The
// refinement waits while the still renders (on a CPU they would share the
// cores for minutes), and goes on once it is done.
TEST(Stills, ASessionsRefinementWaitsForItsStill) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = ClientOf(server, 60s);
  v1::CreateSessionRequest request = SmallSession("ct-bone", 96, 64, 65536);
  request.mutable_stream()->set_error_target(0);  // refines for ever
  const std::string session = client.CreateSession(request).session_id();
  const int spp = SppForSeconds(client, session, 3.0);
  auto stream = client.Attach(session);
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame& f) { return f.accumulated_spp() >= 8; }, 30s));

  std::atomic<int> frames_during{0};
  std::atomic<bool> rendering{false}, done{false};
  std::thread counter([&] {
    while (!done) {
      auto message = stream->Next(100ms);
      if (message && message->has_frame() && rendering) ++frames_during;
    }
  });
  SnapshotOptions wait;
  wait.on_progress = [&](const v1::SnapshotProgress& p) {
    if (p.spp_done() > 0 && !rendering.exchange(true)) frames_during = 0;  // frames in flight before it are not counted
  };
  EXPECT_NO_THROW(client.Snapshot(StillOf(session, spp), wait));
  rendering = false;
  const int during = frames_during;
  done = true;
  counter.join();
  EXPECT_LE(during, 2) << "the session refined beside its still";
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 30s)) << "the refinement did not go on";
}

// A cancel from another thread (a window closing) ends the wait at once.
TEST(Stills, ASnapshotIsCancelledFromAnotherThread) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = ClientOf(server, 60s);
  const std::string session = client.CreateSession(SmallSession()).session_id();
  std::atomic<bool> cancel{false};
  SnapshotOptions wait;
  wait.cancel = &cancel;
  wait.on_progress = [&](const v1::SnapshotProgress&) { cancel = true; };
  const auto start = std::chrono::steady_clock::now();
  ExpectRpcError([&] { client.Snapshot(StillOf(session, 16384), wait); }, grpc::StatusCode::CANCELLED, "cancelled");
  EXPECT_LT(Seconds(std::chrono::steady_clock::now() - start), 5.0);
  // The server stops rendering it: another session's frame comes soon.
  const auto other = client.CreateSession(SmallSession());
  auto stream = client.Attach(other.session_id());
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 10s)) << "the cancelled still still renders";
}

}  // namespace
}  // namespace cinevol::testing

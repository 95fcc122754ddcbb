// Prometheus metrics (--metrics-listen): a real server, a session to its
// final frame, a limit refusal and errors, then /metrics scraped over
// loopback HTTP and checked: the counters moved, no session id is a label,
// and promtool accepts the exposition.
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <string>

#include "metrics_scrape.h"
#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

TEST(Metrics, ServedOnMetricsListenAndCounted) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--metrics-listen", "127.0.0.1:0", "--max-lights", "2"});
  ASSERT_TRUE(server.running()) << server.Log();
  const int port = MetricsPort(server);
  ASSERT_GT(port, 0) << server.Log();
  Client client = server.Connect();

  // A session to its final frame, with a few events.
  const auto created = client.CreateSession(SmallSession());
  auto stream = client.Attach(created.session_id());
  ASSERT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 60s));
  for (int i = 1; i <= 3; ++i) {
    v1::SessionEvent e = Orbit(i);
    e.set_seq(std::uint64_t(i));
    stream->Send(e);
  }
  ASSERT_TRUE(WaitFinal(*stream, 3)) << server.Log();

  // One limit refusal (three lights over --max-lights 2: presets have two) and other errors.
  v1::CreateSessionRequest lights = SmallSession();
  lights.mutable_scene()->mutable_transfer_function()->set_preset("ct-bone");
  for (int i = 0; i < 3; ++i) lights.mutable_scene()->add_lights()->mutable_point()->set_intensity(1);
  ExpectRpcError([&] { client.CreateSession(lights); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-lights");
  ExpectRpcError([&] { client.CreateSession(SmallSession("ct-bone", 0, 0)); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "viewport.width");
  ExpectRpcError([&] { client.CloseSession("no-such-session"); }, grpc::StatusCode::NOT_FOUND, "no-such-session");

  // The sweeper sets the session gauges every 200 ms.
  std::string text;
  ASSERT_TRUE(Eventually(
      [&] {
        text = HttpGet(port, "/metrics").value_or("");
        return Sample(text, R"(cinevol_sessions{state="idle"})") +
                   Sample(text, R"(cinevol_sessions{state="rendering"})") >=
               1;
      },
      10s))
      << text;

  EXPECT_GT(Sample(text, "cinevol_frames_sent_total"), 0) << text;
  EXPECT_GT(Sample(text, "cinevol_frames_rendered_total"), 0) << text;
  EXPECT_GE(Sample(text, "cinevol_frames_dropped_total"), 0) << text;
  EXPECT_GT(Sample(text, "cinevol_sent_bytes_total"), 0) << text;
  EXPECT_GE(Sample(text, "cinevol_events_received_total"), 3) << text;
  EXPECT_GE(Sample(text, "cinevol_events_coalesced_total"), 0) << text;
  EXPECT_EQ(Sample(text, R"(cinevol_limit_refusals_total{limit="max-lights"})"), 1) << text;
  EXPECT_GE(Sample(text, R"(cinevol_errors_total{code="INVALID_ARGUMENT"})"), 1) << text;
  EXPECT_GE(Sample(text, R"(cinevol_errors_total{code="NOT_FOUND"})"), 1) << text;
  for (const char* stage : {"render", "denoise", "tonemap", "encode", "send"}) {
    EXPECT_GT(Sample(text, std::string(R"(cinevol_stage_seconds_count{stage=")") + stage + "\"}"), 0)
        << stage << "\n" << text;
  }
  EXPECT_GT(Sample(text, R"(cinevol_stage_seconds_bucket{stage="render",le="+Inf"})"), 0) << text;
  EXPECT_GT(Sample(text, "cinevol_volume_memory_bytes"), 0) << text;
  EXPECT_EQ(Sample(text, R"(cinevol_uploads_total{result="ok"})"), 0) << text;
  EXPECT_EQ(Sample(text, "cinevol_connections_shed_total"), 0) << text;
  EXPECT_EQ(Sample(text, R"(cinevol_sessions{state="starting"})"), 0) << text;
  // Bounded labels only: no session ids, volume ids or principals.
  EXPECT_EQ(text.find(created.session_id()), std::string::npos) << text;
  EXPECT_EQ(text.find("phantom"), std::string::npos) << text;
  EXPECT_EQ(text.find("anonymous"), std::string::npos) << text;
  EXPECT_FALSE(HttpGet(port, "/nothing-here")) << "only /metrics is served";

  // promtool lints the exposition (names, types, units).
  if (std::system("command -v promtool > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "promtool not found (Debian package 'prometheus'); the exposition was not linted";
  }
  const std::filesystem::path scraped = scratch / "metrics.txt", lint = scratch / "promtool.txt";
  std::ofstream(scraped) << text;
  const int rc = std::system(("timeout 30 promtool check metrics < '" + scraped.string() + "' > '" + lint.string() +
                              "' 2>&1")
                                 .c_str());
  std::ifstream in(lint);
  const std::string lint_text{std::istreambuf_iterator<char>(in), {}};
  EXPECT_EQ(rc, 0) << lint_text << "\n" << text;
  client.CloseSession(created.session_id());
}

TEST(Metrics, BadMetricsListenIsAnInputError) {
  ScratchDir scratch;
  // A port in use: bound and listening here.
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof address;
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(listen(fd, 1), 0);
  ASSERT_EQ(getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length), 0);
  const std::string taken = "127.0.0.1:" + std::to_string(ntohs(address.sin_port));
  for (const std::string& bad : {std::string("not-an-address"), std::string("127.0.0.1:99999"), taken}) {
    const auto [code, log] =
        RunProgram(ServerPath(),
                   {"--listen", "127.0.0.1:0", "--backend", "cpu", "--volume", "phantom:cube?size=16",
                    "--metrics-listen", bad},
                   scratch / "server.log", 60s);
    EXPECT_EQ(code, 2) << bad << ": " << log;
    EXPECT_NE(log.find("--metrics-listen " + bad), std::string::npos) << log;
  }
  close(fd);
}

}  // namespace
}  // namespace cinevol::testing

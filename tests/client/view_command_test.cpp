// `cinevol view FILE` as a new user runs it: it starts a server and the
// page's gateway of its own, loads the file, prints the page's address (which
// answers), and on Ctrl-C stops both; wrong flags are one clear line.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <regex>

#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), {}};
}

// The first match of `pattern`'s group 1 in what `log` holds within `timeout`; empty when none came.
std::string AwaitInLog(const fs::path& log, const std::regex& pattern, std::chrono::seconds timeout) {
  for (auto end = std::chrono::steady_clock::now() + timeout; std::chrono::steady_clock::now() < end;) {
    std::smatch match;
    const std::string text = ReadText(log);
    if (std::regex_search(text, match, pattern)) return match[1];
    std::this_thread::sleep_for(100ms);
  }
  return {};
}

// Whether something listens on 127.0.0.1:port.
bool Listening(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool connected = connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  close(fd);
  return connected;
}

// The status line of a GET of `path` on 127.0.0.1:port with Host `host`.
std::string HttpStatusLine(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval timeout{10, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::string answer;
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
    const std::string request = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
                                "\r\nConnection: close\r\n\r\n";
    if (send(fd, request.data(), request.size(), 0) == ssize_t(request.size())) {
      char buffer[512];
      const ssize_t n = recv(fd, buffer, sizeof buffer, 0);
      if (n > 0) answer.assign(buffer, std::size_t(n));
    }
  }
  close(fd);
  return answer.substr(0, answer.find("\r\n"));
}

TEST(CinevolView, OpensAFileOnItsOwnServerAndStopsWhatItStartedOnCtrlC) {
  ScratchDir scratch;
  WriteSmallNrrd(scratch / "small.nrrd");
  const fs::path log = scratch / "view.log";
  const pid_t view = Spawn(CliPath(), {"view", (scratch / "small.nrrd").string(), "--backend", "cpu", "--preset",
                                       "ct-bone", "--logs", scratch.path().string()},
                           log);
  ASSERT_GT(view, 0);
  const std::string url = AwaitInLog(log, std::regex(R"(open (http://\S+))"), 120s);
  ASSERT_FALSE(url.empty()) << ReadText(log);
  std::smatch parts;
  ASSERT_TRUE(std::regex_match(url, parts, std::regex(R"(http://127\.0\.0\.1:(\d+)(/\?volume=small&preset=ct-bone))")))
      << url;
  const int gateway_port = std::stoi(parts[1]);
  EXPECT_EQ(HttpStatusLine(gateway_port, parts[2]), "HTTP/1.1 200 OK") << "the page at " << url;
  const std::string server = AwaitInLog(log, std::regex(R"(on server (127\.0\.0\.1:\d+))"), 1s);
  ASSERT_FALSE(server.empty()) << ReadText(log);
  ClientOptions options;
  options.address = server;
  Client client(options);
  const auto volumes = client.ListVolumes();
  EXPECT_TRUE(std::any_of(volumes.begin(), volumes.end(), [](const v1::VolumeInfo& v) { return v.id() == "small"; }));
  const int server_port = std::stoi(server.substr(server.find(':') + 1));

  kill(view, SIGINT);
  const int status = WaitExit(view, 30s);
  ASSERT_NE(status, -1) << "cinevol view did not stop on Ctrl-C";
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << ReadText(log);
  EXPECT_TRUE(Eventually([&] { return !Listening(server_port) && !Listening(gateway_port); }, 20s))
      << "what cinevol view started still listens";
}

TEST(CinevolView, WrongSourcesAreOneClearLine) {
  ScratchDir scratch;
  auto run = [&](const std::vector<std::string>& args) { return RunProgram(CliPath(), args, scratch / "cli.log", 60s); };
  auto [code, out] = run({"view"});
  EXPECT_NE(code, 0);
  EXPECT_NE(out.find("give a volume PATH or --pacs NAME"), std::string::npos) << out;
  std::tie(code, out) = run({"view", (scratch / "absent.nii").string()});
  EXPECT_NE(out.find("no such file or folder"), std::string::npos) << out;
  std::tie(code, out) = run({"view", "--pacs", "main", "--patient-id", "X"});
  EXPECT_NE(out.find("--pacs NAME=URL"), std::string::npos) << out;
}

}  // namespace
}  // namespace cinevol::testing

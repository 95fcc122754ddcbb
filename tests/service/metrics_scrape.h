// Scraping a test server's /metrics over loopback HTTP: the port it logged,
// the page, one sample's value.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <optional>
#include <regex>
#include <sstream>
#include <string>

#include "server_process.h"
#include "service_test_support.h"

namespace cinevol::testing {

// GET `path` from 127.0.0.1:`port` (HTTP/1.0, 5 s timeouts); the body of a
// 200 answer, or nothing.
inline std::optional<std::string> HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::nullopt;
  timeval timeout{5, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string response;
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
    const std::string request = "GET " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
    if (send(fd, request.data(), request.size(), MSG_NOSIGNAL) == ssize_t(request.size())) {
      char buffer[8192];
      for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0 && response.size() < (16u << 20);) {
        response.append(buffer, std::size_t(n));
      }
    }
  }
  close(fd);
  const auto body = response.find("\r\n\r\n");
  if (response.rfind("HTTP/1.1 200", 0) != 0 && response.rfind("HTTP/1.0 200", 0) != 0) return std::nullopt;
  if (body == std::string::npos) return std::nullopt;
  return response.substr(body + 4);
}

// The value of the sample `series` (name and labels exactly as exposed), or -1.
inline double Sample(const std::string& text, const std::string& series) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.size() > series.size() && line.compare(0, series.size(), series) == 0 && line[series.size()] == ' ') {
      return std::stod(line.substr(series.size() + 1));
    }
  }
  return -1;
}

// The metrics port the server logged ("metrics on http://HOST:PORT/metrics").
inline int MetricsPort(const ServerProcess& server) {
  static const std::regex logged(R"(metrics on http://[^ ]*:(\d+)/metrics)");
  int port = 0;
  Eventually(
      [&] {
        std::smatch m;
        const std::string log = server.Log();
        if (std::regex_search(log, m, logged)) port = std::stoi(m[1]);
        return port > 0;
      },
      std::chrono::seconds(10));
  return port;
}

}  // namespace cinevol::testing

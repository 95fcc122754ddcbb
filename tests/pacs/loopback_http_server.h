// A tiny HTTP server for the PACS tests that a real PACS cannot stand in for:
// one that redirects, hangs, sends garbage or too much. It listens on
// 127.0.0.1 on a port of its own (bound to port 0), answers one request per
// connection on a thread per connection (at most kMaxConnections in its life),
// and counts what it saw: connections, requests, the most answered at once,
// the bytes it managed to send. Every wait in it is bounded.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cinevol::testing {

struct HttpAnswer {
  std::string head;                    // status line and headers, through the blank line
  std::string body;                    // sent after the head
  std::size_t filler_bytes = 0;        // then this many more bytes of 'x' (a body past a cap)
  std::chrono::milliseconds delay{0};  // waited before anything is sent (cut short when the server stops)
};

// An answer with `status`, `content_type`, the body's length and `Connection: close`.
inline HttpAnswer Answer(int status, const std::string& content_type, std::string body,
                         const std::string& extra_headers = {}) {
  HttpAnswer answer;
  answer.head = "HTTP/1.1 " + std::to_string(status) + " Canned\r\nContent-Type: " + content_type +
                "\r\nContent-Length: " + std::to_string(body.size()) + "\r\nConnection: close\r\n" + extra_headers +
                "\r\n";
  answer.body = std::move(body);
  return answer;
}

struct HttpRequestSeen {
  std::string method;
  std::string target;  // the path and query, as sent
  std::string head;    // the request line and headers
};

class LoopbackHttpServer {
 public:
  using Handler = std::function<HttpAnswer(const HttpRequestSeen&)>;
  static constexpr int kMaxConnections = 64;

  explicit LoopbackHttpServer(Handler handler) : handler_(std::move(handler)) {
    listener_ = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof address;
    if (listener_ < 0 || bind(listener_, reinterpret_cast<sockaddr*>(&address), size) != 0 ||
        listen(listener_, 64) != 0 || getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
      if (listener_ >= 0) close(listener_);
      throw std::runtime_error("LoopbackHttpServer: cannot listen on 127.0.0.1");
    }
    port_ = ntohs(address.sin_port);
    acceptor_ = std::thread([this] { AcceptLoop(); });
  }

  ~LoopbackHttpServer() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    acceptor_.join();
    close(listener_);
    std::vector<std::thread> connections;
    {
      std::lock_guard lock(mutex_);
      connections.swap(connections_);
    }
    for (std::thread& connection : connections) connection.join();
  }

  int port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  int connections() const { return accepted_.load(); }
  int most_at_once() const { return most_at_once_.load(); }
  std::size_t bytes_sent() const { return bytes_sent_.load(); }
  std::vector<HttpRequestSeen> requests() const {
    std::lock_guard lock(mutex_);
    return requests_;
  }

 private:
  void AcceptLoop() {
    while (!Stopping()) {
      pollfd ready{listener_, POLLIN, 0};
      if (poll(&ready, 1, 50) <= 0) continue;
      const int connection = accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
      if (connection < 0) continue;
      if (accepted_.load() >= kMaxConnections) {
        close(connection);
        continue;
      }
      ++accepted_;
      std::lock_guard lock(mutex_);
      connections_.emplace_back([this, connection] { Serve(connection); });
    }
  }

  bool Stopping() const {
    std::lock_guard lock(mutex_);
    return stopping_;
  }

  // Reads the request's head (at most 64 KiB, 5 s) and its body, if it declares one (at most 8 MiB).
  static bool ReadRequest(int connection, HttpRequestSeen& request) {
    const timeval timeout{5, 0};
    setsockopt(connection, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    setsockopt(connection, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
    std::string data;
    char buffer[16384];
    std::size_t head_end;
    while ((head_end = data.find("\r\n\r\n")) == std::string::npos) {
      const ssize_t got = recv(connection, buffer, sizeof buffer, 0);
      if (got <= 0 || data.size() > 65536) return false;
      data.append(buffer, std::size_t(got));
    }
    const std::size_t first_space = data.find(' ');
    const std::size_t second_space = data.find(' ', first_space + 1);
    if (first_space == std::string::npos || second_space == std::string::npos) return false;
    request.method = data.substr(0, first_space);
    request.target = data.substr(first_space + 1, second_space - first_space - 1);
    request.head = data.substr(0, head_end);
    std::string lower = data.substr(0, head_end);
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    const std::size_t length_at = lower.find("\r\ncontent-length:");
    const std::size_t length =
        length_at == std::string::npos ? 0 : std::strtoul(lower.c_str() + length_at + 17, nullptr, 10);
    std::size_t body = data.size() - head_end - 4;
    while (body < length && body < (std::size_t{8} << 20)) {
      const ssize_t got = recv(connection, buffer, sizeof buffer, 0);
      if (got <= 0) return false;
      body += std::size_t(got);
    }
    return true;
  }

  bool Send(int connection, const char* data, std::size_t size) {
    while (size > 0) {
      const ssize_t sent = send(connection, data, size, MSG_NOSIGNAL);
      if (sent <= 0) return false;  // the client went away (or aborted the transfer)
      bytes_sent_ += std::size_t(sent);
      data += sent;
      size -= std::size_t(sent);
    }
    return true;
  }

  void Serve(int connection) {
    HttpRequestSeen request;
    if (ReadRequest(connection, request)) {
      {
        std::lock_guard lock(mutex_);
        requests_.push_back(request);
      }
      const int now = ++at_once_;
      for (int most = most_at_once_.load(); now > most && !most_at_once_.compare_exchange_weak(most, now);) {
      }
      const HttpAnswer answer = handler_(request);
      {
        std::unique_lock lock(mutex_);
        wake_.wait_for(lock, answer.delay, [this] { return stopping_; });
      }
      --at_once_;  // before the answer goes: once the client has it, it may ask again at once
      if (!Stopping()) SendAnswer(connection, answer);
    }
    shutdown(connection, SHUT_RDWR);
    close(connection);
  }

  void SendAnswer(int connection, const HttpAnswer& answer) {
    if (!Send(connection, answer.head.data(), answer.head.size())) return;
    if (!Send(connection, answer.body.data(), answer.body.size())) return;
    const std::string filler(65536, 'x');
    for (std::size_t left = answer.filler_bytes; left > 0 && !Stopping();) {
      const std::size_t chunk = std::min(left, filler.size());
      if (!Send(connection, filler.data(), chunk)) return;
      left -= chunk;
    }
  }

  Handler handler_;
  int listener_ = -1;
  int port_ = 0;
  std::thread acceptor_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::vector<std::thread> connections_;
  std::vector<HttpRequestSeen> requests_;
  std::atomic<int> accepted_{0};
  std::atomic<int> at_once_{0};
  std::atomic<int> most_at_once_{0};
  std::atomic<std::size_t> bytes_sent_{0};
};

}  // namespace cinevol::testing

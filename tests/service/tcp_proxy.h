// A loopback TCP proxy a test controls: it forwards every connection to a
// server port and can cut all connections at once, as a network drop does,
// while it keeps accepting new ones.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace cinevol::testing {

class TcpProxy {
 public:
  explicit TcpProxy(int target_port) : target_port_(target_port) {
    listener_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address);
    listen(listener_, 16);
    socklen_t size = sizeof address;
    getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &size);
    port_ = ntohs(address.sin_port);
    pipe(wake_);
    thread_ = std::thread([this] { Run(); });
  }
  ~TcpProxy() {
    stop_ = true;
    Wake();
    thread_.join();
    CloseAll();
    close(listener_);
    close(wake_[0]);
    close(wake_[1]);
  }

  int port() const { return port_; }
  // Closes every open connection, both sides.
  void CutAll() {
    cut_ = true;
    Wake();
    while (cut_) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  int connections_accepted() const { return accepted_; }

 private:
  void Wake() {
    const char c = 0;
    write(wake_[1], &c, 1);
  }
  void CloseAll() {
    for (auto [a, b] : pairs_) {
      close(a);
      close(b);
    }
    pairs_.clear();
  }
  int Connect() {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(target_port_);
    if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      close(fd);
      return -1;
    }
    return fd;
  }
  // Copies what `from` has to `to`; false when either side closed.
  static bool Forward(int from, int to) {
    char buffer[65536];
    const ssize_t n = read(from, buffer, sizeof buffer);
    if (n <= 0) return false;
    for (ssize_t done = 0; done < n;) {
      const ssize_t w = write(to, buffer + done, n - done);
      if (w <= 0) return false;
      done += w;
    }
    return true;
  }
  void Run() {
    while (!stop_) {
      std::vector<pollfd> fds{{listener_, POLLIN, 0}, {wake_[0], POLLIN, 0}};
      for (auto [a, b] : pairs_) {
        fds.push_back({a, POLLIN, 0});
        fds.push_back({b, POLLIN, 0});
      }
      if (poll(fds.data(), fds.size(), 1000) <= 0) continue;
      if (fds[1].revents) {
        char drain[64];
        read(wake_[0], drain, sizeof drain);
        if (cut_) {
          CloseAll();
          cut_ = false;
        }
        continue;
      }
      for (std::size_t i = 0; i < pairs_.size(); ++i) {
        const pollfd& a = fds[2 + 2 * i];
        const pollfd& b = fds[3 + 2 * i];
        bool open = true;
        if (a.revents) open = Forward(pairs_[i].first, pairs_[i].second);
        if (open && b.revents) open = Forward(pairs_[i].second, pairs_[i].first);
        if (!open) {
          close(pairs_[i].first);
          close(pairs_[i].second);
          pairs_[i] = {-1, -1};
        }
      }
      if (fds[0].revents & POLLIN) {
        const int client = accept(listener_, nullptr, nullptr);
        const int server = Connect();
        if (client >= 0 && server >= 0) {
          pairs_.push_back({client, server});
          ++accepted_;
        } else {
          if (client >= 0) close(client);
          if (server >= 0) close(server);
        }
      }
      std::erase_if(pairs_, [](const std::pair<int, int>& p) { return p.first < 0; });
    }
  }

  int target_port_;
  int listener_ = -1, port_ = 0;
  int wake_[2] = {-1, -1};
  std::atomic<bool> stop_{false}, cut_{false};
  std::atomic<int> accepted_{0};
  std::vector<std::pair<int, int>> pairs_;  // client side, server side; owned by the proxy thread
  std::thread thread_;
};

}  // namespace cinevol::testing

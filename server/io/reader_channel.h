// One end of the socket between a cinevol process and a cinevol-reader child
// (reader_cage.h): length-prefixed protobuf messages, descriptors beside them.
// The parent treats whatever arrives as hostile: a message over the size
// limit, one that does not parse or a closed socket is a ChannelError.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace google::protobuf {
class MessageLite;
}

namespace cinevol {

// A file descriptor, closed when dropped.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { Reset(); }
  UniqueFd(UniqueFd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept {
    if (this != &o) {
      Reset();
      fd_ = std::exchange(o.fd_, -1);
    }
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;

  int get() const { return fd_; }
  explicit operator bool() const { return fd_ >= 0; }
  int Release() { return std::exchange(fd_, -1); }
  void Reset(int fd = -1);

 private:
  int fd_ = -1;
};

class ChannelError : public std::runtime_error {
 public:
  explicit ChannelError(const std::string& what) : std::runtime_error(what) {}
};

class ReaderChannel {
 public:
  // The most bytes one message may have (a label table or a folder's series
  // list are the largest), and the most descriptors beside one.
  static constexpr std::size_t kMaxMessageBytes = std::size_t{16} << 20;
  static constexpr std::size_t kMaxFds = 250;

  explicit ReaderChannel(UniqueFd socket) : socket_(std::move(socket)) {}
  int fd() const { return socket_.get(); }

  // Sends `message`, with `fds` (at most kMaxFds, still the caller's) beside it.
  void Send(const google::protobuf::MessageLite& message, const std::vector<int>& fds = {});
  // Receives one message into `message`, adding the descriptors that came
  // with it to `fds`. Before each read it calls `wait`, which returns once the
  // socket is readable or throws (the parent's deadline and cancelling);
  // without one, reads block.
  void Receive(google::protobuf::MessageLite& message, std::vector<UniqueFd>& fds,
               const std::function<void()>& wait = {});

 private:
  // Reads exactly `size` bytes into `out`, collecting descriptors.
  void ReadExactly(char* out, std::size_t size, std::vector<UniqueFd>& fds, const std::function<void()>& wait);

  UniqueFd socket_;
};

}  // namespace cinevol

// ReaderChannel: framing over a Unix stream socket, SCM_RIGHTS beside it.
#include "io/reader_channel.h"

#include <google/protobuf/message_lite.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <fmt/format.h>

namespace cinevol {

void UniqueFd::Reset(int fd) {
  if (fd_ >= 0) close(fd_);
  fd_ = fd;
}

void ReaderChannel::Send(const google::protobuf::MessageLite& message, const std::vector<int>& fds) {
  std::string bytes;
  if (!message.SerializeToString(&bytes) || bytes.size() > kMaxMessageBytes || fds.size() > kMaxFds) {
    throw ChannelError("a message too large to send");
  }
  const std::uint32_t size = std::uint32_t(bytes.size());
  std::string frame(4, '\0');
  for (int i = 0; i < 4; ++i) frame[i] = char((size >> (8 * i)) & 0xff);
  frame += bytes;
  std::size_t sent = 0;
  std::vector<char> control(CMSG_SPACE(sizeof(int) * kMaxFds));
  while (sent < frame.size()) {
    iovec io{frame.data() + sent, frame.size() - sent};
    msghdr msg{};
    msg.msg_iov = &io;
    msg.msg_iovlen = 1;
    if (sent == 0 && !fds.empty()) {  // the descriptors ride on the frame's first bytes
      msg.msg_control = control.data();
      msg.msg_controllen = CMSG_SPACE(sizeof(int) * fds.size());
      cmsghdr* c = CMSG_FIRSTHDR(&msg);
      c->cmsg_level = SOL_SOCKET;
      c->cmsg_type = SCM_RIGHTS;
      c->cmsg_len = CMSG_LEN(sizeof(int) * fds.size());
      std::memcpy(CMSG_DATA(c), fds.data(), sizeof(int) * fds.size());
    }
    const ssize_t n = sendmsg(socket_.get(), &msg, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw ChannelError(fmt::format("the reader's socket closed ({})", std::strerror(errno)));
    sent += std::size_t(n);
  }
}

void ReaderChannel::ReadExactly(char* out, std::size_t size, std::vector<UniqueFd>& fds,
                                const std::function<void()>& wait) {
  std::vector<char> control(CMSG_SPACE(sizeof(int) * kMaxFds));
  for (std::size_t got = 0; got < size;) {
    if (wait) wait();
    iovec io{out + got, size - got};
    msghdr msg{};
    msg.msg_iov = &io;
    msg.msg_iovlen = 1;
    msg.msg_control = control.data();
    msg.msg_controllen = control.size();
    const ssize_t n = recvmsg(socket_.get(), &msg, MSG_CMSG_CLOEXEC | (wait ? MSG_DONTWAIT : 0));
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_RIGHTS) continue;
      const std::size_t count = (c->cmsg_len - CMSG_LEN(0)) / sizeof(int);
      for (std::size_t i = 0; i < count; ++i) {
        int fd;
        std::memcpy(&fd, CMSG_DATA(c) + i * sizeof(int), sizeof fd);
        fds.emplace_back(fd);
      }
    }
    if (msg.msg_flags & MSG_CTRUNC) throw ChannelError("more descriptors than a message may carry");
    if (n == 0) throw ChannelError("the other end closed the socket");
    if (n < 0) throw ChannelError(fmt::format("the socket failed ({})", std::strerror(errno)));
    got += std::size_t(n);
  }
}

void ReaderChannel::Receive(google::protobuf::MessageLite& message, std::vector<UniqueFd>& fds,
                            const std::function<void()>& wait) {
  unsigned char prefix[4];
  ReadExactly(reinterpret_cast<char*>(prefix), 4, fds, wait);
  const std::uint32_t size = std::uint32_t(prefix[0]) | std::uint32_t(prefix[1]) << 8 |
                             std::uint32_t(prefix[2]) << 16 | std::uint32_t(prefix[3]) << 24;
  if (size > kMaxMessageBytes) throw ChannelError(fmt::format("a message of {} bytes, over the limit", size));
  std::string bytes(size, '\0');
  ReadExactly(bytes.data(), size, fds, wait);
  if (!message.ParseFromString(bytes)) throw ChannelError("a message that does not parse");
}

}  // namespace cinevol

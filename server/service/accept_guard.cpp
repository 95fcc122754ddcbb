// The accept guard. gRPC 1.51 (Debian 12) stops listening for good when
// accept4 fails with EMFILE or ENFILE: after a flood of idle connections the
// process lives on but never accepts again. This file defines accept4, which
// cinevol-server exports (CMakeLists.txt: --export-dynamic-symbol) so that
// libgrpc's calls land here first:
//  - past the descriptor cap, a new connection is closed at once, keeping
//    descriptors free for volumes, uploads and the connections already held;
//  - out of descriptors, a spare one kept open for the purpose is given up
//    to accept and close the waiting connection, and gRPC is told EAGAIN, so
//    it keeps listening for the next.
#include <dlfcn.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <mutex>

#include "service/connection_limits.h"

namespace cinevol::service {
namespace {

using Accept4 = int (*)(int, sockaddr*, socklen_t*, int);

std::atomic<int> max_descriptor{0};
std::atomic<std::uint64_t> shed{0};
std::mutex spare_mu;
int spare = -1;  // guarded by spare_mu

Accept4 RealAccept4() {
  static const auto real = reinterpret_cast<Accept4>(dlsym(RTLD_NEXT, "accept4"));
  return real;
}

// Out of descriptors: accept and close what waits, with the spare's slot.
void ShedWaiting(int listener) {
  std::lock_guard lock(spare_mu);
  for (int i = 0; i < 64 && spare >= 0; ++i) {
    close(spare);
    const int fd = RealAccept4()(listener, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd >= 0) {
      close(fd);
      ++shed;
    }
    spare = open("/dev/null", O_RDONLY | O_CLOEXEC);
    if (fd < 0) break;
  }
}

}  // namespace

void ConfigureAcceptGuard(int max) {
  std::lock_guard lock(spare_mu);
  if (spare < 0) spare = open("/dev/null", O_RDONLY | O_CLOEXEC);
  max_descriptor = max;
}

std::uint64_t ShedConnections() { return shed; }

}  // namespace cinevol::service

extern "C" int accept4(int listener, sockaddr* address, socklen_t* length, int flags) {
  using namespace cinevol::service;
  for (;;) {
    const int fd = RealAccept4()(listener, address, length, flags);
    const int max = max_descriptor.load(std::memory_order_relaxed);
    if (max <= 0) return fd;
    if (fd >= max) {  // over the cap: closed now; try the next waiting one
      close(fd);
      ++shed;
      continue;
    }
    if (fd < 0 && (errno == EMFILE || errno == ENFILE)) {
      ShedWaiting(listener);
      errno = EAGAIN;
    }
    return fd;
  }
}

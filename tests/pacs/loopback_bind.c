/* Preloaded into the Orthanc the tests start (LD_PRELOAD): Orthanc 1.10 has no
 * option for the address it listens on and binds every interface, so a bind
 * to the wildcard address becomes a bind to the loopback one. Nothing the
 * tests start is then reachable from another machine, even for a moment. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/socket.h>

typedef int (*BindFunction)(int, const struct sockaddr*, socklen_t);

int bind(int fd, const struct sockaddr* address, socklen_t length) {
  static BindFunction real_bind;
  if (real_bind == NULL) real_bind = (BindFunction)dlsym(RTLD_NEXT, "bind");
  if (address != NULL && address->sa_family == AF_INET && length >= sizeof(struct sockaddr_in)) {
    struct sockaddr_in loopback;
    memcpy(&loopback, address, sizeof loopback);
    if (loopback.sin_addr.s_addr == htonl(INADDR_ANY)) loopback.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return real_bind(fd, (const struct sockaddr*)&loopback, sizeof loopback);
  }
  if (address != NULL && address->sa_family == AF_INET6 && length >= sizeof(struct sockaddr_in6)) {
    struct sockaddr_in6 loopback;
    memcpy(&loopback, address, sizeof loopback);
    if (memcmp(&loopback.sin6_addr, &in6addr_any, sizeof in6addr_any) == 0) loopback.sin6_addr = in6addr_loopback;
    return real_bind(fd, (const struct sockaddr*)&loopback, sizeof loopback);
  }
  return real_bind(fd, address, length);
}

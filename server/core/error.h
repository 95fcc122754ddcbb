// Exceptions thrown inside cinevol. The service maps them to gRPC status codes
// in one place; the command line prints their message and exits non-zero.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace cinevol {

// Bad input from a user: a file, a folder, a scene or a request. The message
// names what was wrong and where (file path, field name).
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

// Bad input that breaks a limit this server was configured with: `flag`
// names the option (e.g. "max-frame-spp"), which the message names too; the
// service counts refusals by it.
class OverLimit : public InputError {
 public:
  OverLimit(std::string flag, const std::string& what) : InputError(what), flag_(std::move(flag)) {}
  const std::string& flag() const { return flag_; }

 private:
  std::string flag_;
};

// Out of a resource the request needs: GPU memory, session slots. The
// service answers RESOURCE_EXHAUSTED; other sessions are unaffected.
class ResourceExhausted : public std::runtime_error {
 public:
  explicit ResourceExhausted(const std::string& what) : std::runtime_error(what) {}
};

// Work stopped before it finished because nobody wants it any more: its
// session closed, its caller went away, or the server is shutting down.
class Cancelled : public std::runtime_error {
 public:
  explicit Cancelled(const std::string& what = "cancelled") : std::runtime_error(what) {}
};

}  // namespace cinevol

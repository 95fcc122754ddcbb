// What every room of the viewer may use: the UI thread's queue for answers
// that arrive on the connection's threads, the line under the panels, and
// the machine-readable lines a script run prints.
#pragma once

#include <google/protobuf/struct.pb.h>

#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace cinevol::viewer {

using Clock = std::chrono::steady_clock;

// Work handed to the UI thread: the answers of calls made on other threads.
class UiQueue {
 public:
  void Later(std::function<void()> f) {
    std::lock_guard lock(mu_);
    due_.push_back(std::move(f));
  }
  // On the UI thread, once a turn.
  void RunDue() {
    std::vector<std::function<void()>> due;
    {
      std::lock_guard lock(mu_);
      due.swap(due_);
    }
    for (auto& f : due) f();
  }

 private:
  std::mutex mu_;
  std::vector<std::function<void()>> due_;
};

// JSON values for the lines scripts read.
google::protobuf::Value TextValue(const std::string& text);
google::protobuf::Value NumberValue(double number);

// "cinevol-viewer: ACTION {JSON}" on stdout, for whoever runs a script (a
// person's clicks print nothing). Patient fields never go in one.
class ScriptLog {
 public:
  explicit ScriptLog(bool scripted) : scripted_(scripted) {}
  bool scripted() const { return scripted_; }
  void Report(const std::string& action, const google::protobuf::Struct& fields) const;

 private:
  bool scripted_;
};

struct ViewerContext {
  explicit ViewerContext(bool scripted) : log(scripted) {}
  UiQueue ui;
  ScriptLog log;
  std::string notice;  // the last message for people (a result or an error)
};

}  // namespace cinevol::viewer

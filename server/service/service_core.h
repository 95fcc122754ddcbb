// What the three services share: the volumes, the devices (one scheduler
// per GPU, or one for the CPU), the encoder and loader pools, the sessions
// and the limits. The gRPC service classes are thin shells over it.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/support/status.h>

#include "cinevol/v1/service.pb.h"
#include "render/renderer.h"
#include "service/auth.h"
#include "service/scheduler.h"
#include "service/session.h"
#include "service/session_requests.h"
#include "service/task_pool.h"
#include "service/volume_registry.h"

namespace cinevol::service {

// Settings of a server; `cinevol-server --help` documents each.
struct ServerOptions {
  std::string listen = "127.0.0.1:50051";
  Backend backend = Backend::kAuto;
  std::vector<int> devices;                              // GPU ids; empty: every usable GPU
  std::vector<std::filesystem::path> data_roots;         // where clients may load volumes from
  std::vector<std::string> volumes;                      // preloaded; empty: phantom:head
  int workers_per_gpu = 4;                               // each its own CUDA stream
  int encode_threads = 0;                                // 0: one per hardware thread
  int max_sessions = 64;
  std::uint64_t max_upload_mb = 2048;
  double detached_session_seconds = 60;                  // a detached session waits this long for a new attach
  SessionLimits limits;
  std::string port_file;                                 // written with the bound port once listening
  std::filesystem::path auth_tokens;                     // "TOKEN PRINCIPAL" lines; empty: no authentication
};

class ServiceCore {
 public:
  explicit ServiceCore(const ServerOptions& options);  // loads the volumes; throws InputError for bad options
  ~ServiceCore();  // ends every session, then stops the workers

  Principal Authenticate(const grpc::CallbackServerContext& context) const {
    return authenticator_.Authenticate(context);
  }
  VolumeRegistry& volumes() { return volumes_; }
  TaskPool& loader() { return loader_; }

  v1::CreateSessionResponse CreateSession(const v1::CreateSessionRequest& request, const Principal& caller);
  std::shared_ptr<Session> FindSession(const std::string& id, const Principal& caller) const;
  void CloseSession(const std::string& id, const Principal& caller);
  // Renders a still of the session's current state on its device;
  // `done` runs on a worker with the result.
  void Snapshot(const v1::SnapshotRequest& request, const Principal& caller,
                std::function<void(grpc::Status, v1::SnapshotResponse)> done);
  v1::ServerStatus Status() const;
  // Ends sessions detached for longer than the options allow.
  void ExpireDetachedSessions();
  // "cuda:0 NVIDIA H100 80GB HBM3, ..." or "cpu (N threads)".
  std::string DeviceSummary() const;

 private:
  Scheduler& LeastLoaded();
  void Forget(const std::string& id);

  ServerOptions options_;
  Backend backend_ = Backend::kCpu;  // resolved: kCpu or kCuda
  Authenticator authenticator_;
  VolumeRegistry volumes_;
  TaskPool encoder_;
  TaskPool loader_;
  std::vector<std::unique_ptr<Scheduler>> schedulers_;
  const Clock::time_point started_ = Clock::now();

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  std::uint64_t next_session_ = 1;
};

}  // namespace cinevol::service

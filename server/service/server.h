// The gRPC server around a ServiceCore: listening, health checking (open to
// anyone: probes) and reflection (authenticated), the sweep that ends expired detached sessions, and an orderly
// shutdown (calls cancelled, sessions ended, workers joined).
#pragma once

#include <grpcpp/grpcpp.h>

#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

#include "service/reflection.h"
#include "service/service_core.h"
#include "service/services.h"

namespace prometheus {
class Exposer;
}

namespace cinevol::service {

class Server {
 public:
  // Loads the volumes and starts listening; throws InputError for bad
  // options or an address it cannot listen on.
  explicit Server(const ServerOptions& options);
  ~Server();  // Shutdown(), then stops as Wait does

  int port() const { return port_; }
  // The port /metrics is served on (--metrics-listen); 0 when off.
  int metrics_port() const { return metrics_port_; }
  // Blocks until Shutdown is asked for, then stops: open calls are
  // cancelled, sessions end, workers join.
  void Wait();
  // Asks the server to drain and stop; returns at once (any thread). The
  // process exits (code 0) within --drain-seconds, even if something hangs.
  void Shutdown();
  // SIGHUP: the PACS credentials file again (the token file reloads apart).
  void ReloadPacsCredentials() { core_->pacs().ReloadCredentials(); }

 private:
  void Sweep();
  void Stop();
  // Serves /metrics on `listen` (--metrics-listen); throws InputError naming the flag.
  void StartMetrics(const std::string& listen);

  std::unique_ptr<ServiceCore> core_;
  double drain_seconds_;
  VolumeServiceImpl volume_service_;
  SessionServiceImpl session_service_;
  PacsServiceImpl pacs_service_;
  ServerServiceImpl server_service_;
  ReflectionService reflection_service_;  // authenticated like the others
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::unique_ptr<prometheus::Exposer> exposer_;  // /metrics, with --metrics-listen
  int metrics_port_ = 0;

  std::mutex mu_;
  std::condition_variable stop_;
  bool stopping_ = false;
  std::once_flag stopped_;
  std::thread sweeper_;
};

}  // namespace cinevol::service

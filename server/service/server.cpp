// Server: gRPC setup and teardown.
#include "service/server.h"

#include <grpcpp/health_check_service_interface.h>
#include <fmt/format.h>
#include <prometheus/exposer.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "core/error.h"
#include "service/call_log.h"
#include "service/connection_limits.h"
#include "runtime/metrics.h"

namespace cinevol::service {
namespace {

// Scenes, events and upload chunks (the client sends 1 MiB chunks). A scene
// within the limits is a few kB; this bounds what one message can make the
// server parse before any check runs.
constexpr int kMaxReceiveBytes = (1 << 20) + (64 << 10);

// What Kubernetes readiness probes ask (docs/deploy.md); "" is liveness.
constexpr const char* kReadinessService = "cinevol.v1.SessionService";

}  // namespace

Server::Server(const ServerOptions& options)
    : core_(std::make_unique<ServiceCore>(options)),
      drain_seconds_(options.drain_seconds),
      volume_service_(core_.get()),
      session_service_(core_.get()),
      pacs_service_(core_.get()),
      server_service_(core_.get()),
      reflection_service_(core_.get(), {v1::VolumeService::service_full_name(), v1::SessionService::service_full_name(),
                                        v1::PacsService::service_full_name(), v1::ServerService::service_full_name(),
                                        "grpc.health.v1.Health"}) {
  if (!options.metrics_listen.empty()) StartMetrics(options.metrics_listen);
  // Health answers without credentials (Kubernetes and Docker probes carry none);
  // it tells only SERVING or NOT_SERVING.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  PrepareDescriptors(options.connections);
  builder.AddListeningPort(options.listen, MakeServerCredentials(options.tls), &port_);
  builder.SetMaxReceiveMessageSize(kMaxReceiveBytes);
  ApplyConnectionLimits(options.connections, builder);
  builder.experimental().SetInterceptorCreators(CallLogInterceptors());
  builder.RegisterService(&volume_service_);
  builder.RegisterService(&session_service_);
  builder.RegisterService(&pacs_service_);
  builder.RegisterService(&server_service_);
  builder.RegisterService(&reflection_service_);
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) {
    throw InputError(fmt::format("--listen {}: cannot listen there (address in use, or not HOST:PORT?)",
                                 options.listen));
  }
  server_->GetHealthCheckService()->SetServingStatus(true);
  server_->GetHealthCheckService()->SetServingStatus(kReadinessService, core_->HasRoomForSession());
  if (!options.port_file.empty()) std::ofstream(options.port_file) << port_ << "\n";
  sweeper_ = std::thread([this] { Sweep(); });
  const std::string host = options.listen.substr(0, options.listen.rfind(':'));
  spdlog::info("cinevol-server listening on {}:{}, rendering on {}", host, port_, core_->DeviceSummary());
}

void Server::StartMetrics(const std::string& listen) {
  const auto colon = listen.rfind(':');
  const std::string port = colon == std::string::npos ? "" : listen.substr(colon + 1);
  if (colon == 0 || port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535) {
    throw InputError(fmt::format("--metrics-listen {}: not HOST:PORT (e.g. 127.0.0.1:9464)", listen));
  }
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(listen, 1);
  } catch (const std::exception&) {
    throw InputError(fmt::format("--metrics-listen {}: cannot listen there (address in use, or not HOST:PORT?)",
                                 listen));
  }
  exposer_->RegisterCollectable(ServerMetrics().registry());
  const std::vector<int> ports = exposer_->GetListeningPorts();
  metrics_port_ = ports.empty() ? 0 : ports.front();
  core_->PublishMetrics(true);
  spdlog::info("cinevol-server metrics on http://{}:{}/metrics", listen.substr(0, colon), metrics_port_);
  if (!IsLoopbackListen(listen)) {
    spdlog::warn("--metrics-listen {}: /metrics is reachable from other machines, without authentication", listen);
  }
}

Server::~Server() {
  Shutdown();
  Stop();
}

void Server::Sweep() {
  std::unique_lock lock(mu_);
  int sweeps = 0;
  while (!stop_.wait_for(lock, std::chrono::milliseconds(200), [&] { return stopping_; })) {
    lock.unlock();
    core_->ExpireDetachedSessions();
    // Readiness: the session service serves while another session fits.
    server_->GetHealthCheckService()->SetServingStatus(kReadinessService, core_->HasRoomForSession());
    core_->calls().CancelOverdue(std::chrono::steady_clock::now());
    if (exposer_) core_->PublishMetrics(++sweeps % 5 == 0);  // GPU memory once a second
    lock.lock();
  }
}

void Server::Shutdown() {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    stopping_ = true;
  }
  stop_.notify_all();
  // Whatever hangs (a load deep in a library, a peer that never reads), the
  // process ends on time: what drained is done, what did not is abandoned.
  std::thread([seconds = drain_seconds_] {
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    spdlog::warn("cinevol-server: still busy after {} s (--drain-seconds); exiting now", seconds);
    std::fflush(nullptr);
    std::_Exit(0);
  }).detach();
}

void Server::Wait() {
  {
    std::unique_lock lock(mu_);
    stop_.wait(lock, [&] { return stopping_; });
  }
  Stop();
}

void Server::Stop() {
  std::call_once(stopped_, [&] {
    spdlog::info("cinevol-server: draining (at most {} s)", drain_seconds_);
    // Draining first: the sweeper's readiness update then reads no room.
    core_->Drain();  // new work refused; sessions end with a notice; frames and stills cancelled
    server_->GetHealthCheckService()->SetServingStatus(false);
    // Calls still open after a moment (uploads, a peer that never reads) are cancelled.
    server_->Shutdown(std::chrono::system_clock::now() +
                      std::chrono::milliseconds(int(std::min(2.0, drain_seconds_ / 4) * 1000)));
    sweeper_.join();
    core_.reset();
    spdlog::info("cinevol-server: stopped");
  });
}

}  // namespace cinevol::service

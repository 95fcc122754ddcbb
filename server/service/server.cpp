// Server: gRPC setup and teardown.
#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>

#include "core/error.h"

namespace cinevol::service {
namespace {

constexpr int kMaxReceiveBytes = 64 << 20;  // scenes and upload chunks; uploads stream in many

}  // namespace

Server::Server(const ServerOptions& options)
    : core_(std::make_unique<ServiceCore>(options)),
      volume_service_(core_.get()),
      session_service_(core_.get()),
      server_service_(core_.get()) {
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, grpc::InsecureServerCredentials(), &port_);
  builder.SetMaxReceiveMessageSize(kMaxReceiveBytes);
  builder.RegisterService(&volume_service_);
  builder.RegisterService(&session_service_);
  builder.RegisterService(&server_service_);
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) {
    throw InputError(fmt::format("--listen {}: cannot listen there (address in use, or not HOST:PORT?)",
                                 options.listen));
  }
  server_->GetHealthCheckService()->SetServingStatus(true);
  if (!options.port_file.empty()) std::ofstream(options.port_file) << port_ << "\n";
  sweeper_ = std::thread([this] { Sweep(); });
  const std::string host = options.listen.substr(0, options.listen.rfind(':'));
  spdlog::info("cinevol-server listening on {}:{}, rendering on {}", host, port_, core_->DeviceSummary());
}

Server::~Server() {
  Shutdown();
  Stop();
}

void Server::Sweep() {
  std::unique_lock lock(mu_);
  while (!stop_.wait_for(lock, std::chrono::milliseconds(200), [&] { return stopping_; })) {
    lock.unlock();
    core_->ExpireDetachedSessions();
    lock.lock();
  }
}

void Server::Shutdown() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  stop_.notify_all();
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
    spdlog::info("cinevol-server: shutting down");
    server_->GetHealthCheckService()->SetServingStatus(false);
    // Calls still open after a moment are cancelled; their reactors finish.
    server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
    sweeper_.join();
    core_.reset();
  });
}

}  // namespace cinevol::service

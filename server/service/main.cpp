// cinevol-server: streams rendered, denoised frames of loaded volumes to
// viewers over gRPC. With no arguments it listens on 127.0.0.1:50051,
// serves the built-in head phantom and renders on a GPU when one is usable.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <thread>

#include "core/error.h"
#include "service/server.h"

namespace {

using cinevol::service::ServerOptions;

void AddOptions(CLI::App& app, ServerOptions& o, std::string& backend) {
  app.set_config("--config", "", "Read these settings from a TOML/INI file (keys as the long flags)");
  app.add_option("--listen", o.listen, "HOST:PORT to listen on (port 0: any free port)")->capture_default_str();
  app.add_option("--backend", backend, "auto (CUDA when a GPU is usable), cpu or cuda")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}))
      ->capture_default_str();
  app.add_option("--devices", o.devices, "GPU ids to render on (default: every usable GPU)")->delimiter(',');
  app.add_option("--data-root", o.data_roots, "Folder clients may load volumes from (repeatable; none: no loading)");
  app.add_option("--volume", o.volumes,
                 "Volume to serve from the start: a file, a DICOM folder or phantom:NAME[?size=N...] "
                 "(repeatable; default phantom:head)");
  app.add_option("--workers-per-gpu", o.workers_per_gpu, "Render threads per GPU, each with its own CUDA stream")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--encode-threads", o.encode_threads, "JPEG encoder threads (0: one per hardware thread)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  app.add_option("--max-sessions", o.max_sessions, "Sessions held at once")->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--max-pixels", o.limits.max_pixels, "Largest viewport, width x height")
      ->check(CLI::Range(1ull, 8192ull * 8192ull))
      ->capture_default_str();
  app.add_option("--max-upload-mb", o.max_upload_mb, "Largest volume upload, MiB")->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--detached-session-seconds", o.detached_session_seconds,
                 "How long a session without a stream waits for one before it ends")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  app.add_option("--auth-tokens", o.auth_tokens,
                 "File of 'TOKEN PRINCIPAL' lines: calls must send 'authorization: Bearer TOKEN' (default: open)");
  app.add_option("--port-file", o.port_file, "Write the port listened on to this file (useful with port 0)");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cinevol-server: remote volumetric path tracing with real-time denoising, over gRPC"};
  ServerOptions options;
  std::string backend = "auto";
  bool verbose = false;
  AddOptions(app, options, backend);
  app.add_flag("-v,--verbose", verbose, "Log debug detail");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info);

  // SIGINT and SIGTERM end the server in order; a thread waits for them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  try {
    options.backend = cinevol::ParseBackend(backend);
    cinevol::service::Server server(options);
    std::thread([&server, signals] {
      int signal = 0;
      sigwait(&signals, &signal);
      server.Shutdown();
    }).detach();
    server.Wait();
  } catch (const cinevol::InputError& e) {
    std::fprintf(stderr, "cinevol-server: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cinevol-server: %s\n", e.what());
    return 1;
  }
  return 0;
}

// cinevol-server: streams rendered, denoised frames of loaded volumes to
// viewers over gRPC. With no arguments it listens on 127.0.0.1:50051,
// serves the built-in head phantom and renders on a GPU when one is usable.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <regex>
#include <thread>

#include "core/error.h"
#include "core/log_safe.h"
#include "service/server.h"

namespace {

using cinevol::service::ConnectionLimits;
using cinevol::service::ServerOptions;
using cinevol::SessionLimits;
using cinevol::service::VolumeLimits;

// What one client may take: every limit of docs/security.md.
void AddLimitOptions(CLI::App& app, ServerOptions& o) {
  auto limit = [&app](const std::string& flag, auto& value, const std::string& what, auto lo, auto hi) {
    app.add_option(flag, value, what)->check(CLI::Range(lo, hi))->capture_default_str()->group("Limits");
  };
  SessionLimits& s = o.limits;
  limit("--max-sessions", o.max_sessions, "Sessions held at once", 1, 100000);
  limit("--max-sessions-per-principal", o.max_sessions_per_principal, "Sessions one principal holds at once", 1,
        100000);
  limit("--min-session-fps", o.min_session_fps,
        "On a GPU server, refuse a new session where every session on its GPU would then get fewer frames a second "
        "than this, by what the GPU was seen to render while busy (0: never)",
        0.0, 1000.0);
  limit("--max-viewers-per-session", s.max_viewers_per_session, "Streams watching one shared session", 1, 100000);
  limit("--max-viewers-per-grant", s.max_viewers_per_grant, "Of them, streams by one share (a link)", 1, 100000);
  limit("--max-grants-per-principal", o.max_grants_per_principal, "Shares (grants) one principal holds at once", 1,
        100000);
  limit("--max-pixels", s.max_pixels, "Largest viewport, width x height", 1ull, 8192ull * 8192ull);
  limit("--max-total-pixels", o.max_total_pixels, "Viewport pixels of all sessions together", 1ull, 1ull << 40);
  limit("--max-frame-spp", s.max_frame_spp, "Samples per pixel of one streamed frame", 1, 65536);
  limit("--max-frame-samples", s.max_frame_samples, "Samples (spp x pixels) of one streamed frame", 1ull, 1ull << 40);
  limit("--max-bounces", s.max_bounces, "Scattering events per path", 0, 256);
  limit("--max-snapshot-spp", s.max_snapshot_spp, "Samples per pixel of a snapshot", 1, 1 << 20);
  limit("--max-snapshot-samples", s.max_snapshot_samples, "Samples (spp x pixels) of a snapshot", 1ull, 1ull << 50);
  limit("--max-movie-samples", s.max_movie_samples, "Samples (frames x spp x pixels) of a movie", 1ull, 1ull << 50);
  limit("--max-tf-points", s.max_tf_points, "Transfer-function control points", 1, 1 << 20);
  app.add_option_function<std::uint64_t>(
         "--max-phase-copies-mb", [&s](std::uint64_t mb) { s.max_phase_copy_bytes = mb << 20; },
         fmt::format("Device memory one session holds in a time series' phase copies, MiB: past it the phases "
                     "ahead of the one shown are kept in a window (default {})",
                     s.max_phase_copy_bytes >> 20))
      ->check(CLI::Range(1, 1 << 24))
      ->group("Limits");
  limit("--max-lights", s.max_lights, "Lights in a scene", 0, 1 << 16);
  limit("--max-events-per-second", s.max_events_per_second, "Events one stream applies per second (more coalesce)",
        1, 1 << 20);
  limit("--unattached-session-seconds", o.unattached_session_seconds,
        "How long a new session waits for its first stream", 0.5, 86400.0);
  limit("--first-message-seconds", o.first_message_seconds, "How long a stream may take to attach", 0.5, 3600.0);
  limit("--max-call-seconds", o.call_seconds,
        "A unary call's work at most, queued or running (a slice, a pick, a search, a new session's framing)", 0.1,
        86400.0);
  VolumeLimits& v = o.volume_limits;
  app.add_option_function<std::uint64_t>("--max-upload-mb", [&v](std::uint64_t mb) { v.max_upload_bytes = mb << 20; },
                                         "Largest volume upload, MiB (default 2048)")
      ->check(CLI::Range(1, 1 << 20))
      ->group("Limits");
  limit("--max-uploads-per-principal", o.max_uploads_per_principal, "Uploads and loads one principal runs at once", 1,
        1024);
  limit("--upload-idle-seconds", o.upload_idle_seconds, "An upload that sends nothing this long ends", 0.5, 3600.0);
  limit("--max-volume-voxels", v.max_voxels, "Voxels of one volume", 1ull, 1ull << 40);
  app.add_option_function<std::uint64_t>(
         "--max-volume-memory-mb", [&v](std::uint64_t mb) { v.max_total_bytes = mb << 20; },
         fmt::format("Host memory of all volumes held, MiB (default {})", v.max_total_bytes >> 20))
      ->check(CLI::Range(1, 1 << 30))
      ->group("Limits");
  app.add_option_function<std::uint64_t>(
         "--max-upload-memory-mb", [&v](std::uint64_t mb) { v.max_upload_bytes_per_principal = mb << 20; },
         fmt::format("Host memory of one principal's uploaded volumes, MiB (default {})",
                     v.max_upload_bytes_per_principal >> 20))
      ->check(CLI::Range(1, 1 << 30))
      ->group("Limits");
  app.add_flag("--resample-uneven", v.resample_uneven,
               "Resample DICOM series with uneven slice gaps onto an even grid (their smallest gap) instead of "
               "refusing them; a request may ask for it alone")
      ->group("Limits");
  limit("--reader-cpu-seconds", v.reader.cpu_seconds, "CPU time of one file's reader (cinevol-reader)", 1.0, 86400.0);
  limit("--reader-seconds", v.reader.wall_seconds, "Time one file's reader may take from start to answer", 1.0,
        86400.0);
  ConnectionLimits& c = o.connections;
  limit("--max-connections", c.max_connections, "Client connections at once (about: counted in descriptors)", 16,
        1 << 24);
  limit("--max-streams-per-connection", c.max_streams_per_connection, "Concurrent calls on one connection", 1,
        1 << 16);
  limit("--handshake-seconds", c.handshake_seconds, "A connection must speak HTTP/2 (and TLS) within this", 1, 3600);
  limit("--keepalive-seconds", c.keepalive_seconds, "Ping quiet connections this often to find dead peers", 1, 86400);
  limit("--transport-memory-mb", c.transport_memory_mb, "Memory gRPC's transport may use", 16ull, 1ull << 20);
}

// The --pacs flags as given; PacsConfigs once parsed.
struct PacsFlags {
  std::vector<std::string> specs;
  std::vector<std::string> auth;  // --pacs-auth: "forward" (every PACS) or "NAME=forward"
  std::string ca_file;
  double timeout_seconds = 120;
  int parallel_fetches = 4;
  std::uint64_t max_series_mb = 4096;

  std::vector<cinevol::pacs::PacsConfig> Configs() const {
    std::vector<cinevol::pacs::PacsConfig> configs;
    for (const std::string& spec : specs) {
      cinevol::pacs::PacsConfig c = cinevol::pacs::ParsePacsSpec(spec);
      c.ca_file = ca_file;
      c.request_timeout = std::chrono::milliseconds(std::int64_t(timeout_seconds * 1000));
      c.parallel_fetches = parallel_fetches;
      c.max_series_bytes = max_series_mb << 20;
      if (Forwards(c.name)) c.credentials.kind = cinevol::pacs::PacsCredentials::Kind::kForward;
      cinevol::pacs::ValidatePacsConfig(c);
      configs.push_back(std::move(c));
    }
    for (const std::string& a : auth) {
      const bool named = a.size() > 8 && a.ends_with("=forward");
      const std::string name = named ? a.substr(0, a.size() - 8) : "";
      const bool known = std::any_of(configs.begin(), configs.end(), [&](const auto& c) { return c.name == name; });
      if (a != "forward" && !(named && known)) {
        throw cinevol::InputError(fmt::format("--pacs-auth: '{}' is neither 'forward' nor NAME=forward for a --pacs NAME",
                                              cinevol::LogSafe(a, 80)));
      }
    }
    return configs;
  }

  // Whether PACS `name` takes the caller's own token.
  bool Forwards(const std::string& name) const {
    return std::any_of(auth.begin(), auth.end(), [&](const std::string& a) { return a == "forward" || a == name + "=forward"; });
  }
};

void AddOptions(CLI::App& app, ServerOptions& o, std::string& backend, std::string& jpeg_encoder, std::string& gpu_wait,
                PacsFlags& pacs) {
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
  app.add_option("--gpu-wait", gpu_wait,
                 "How render threads wait for their GPU: yield (spin, but give the core to other threads between "
                 "checks), auto (CUDA's choice: spinning), spin or block (sleep until the GPU is done)")
      ->check(CLI::IsMember({"auto", "spin", "yield", "block"}))
      ->capture_default_str();
  app.add_option("--pixels-in-flight-per-gpu", o.pixels_in_flight_per_gpu,
                 "Pixels the frames rendering at once on a GPU may have together (one frame always may; 0: no "
                 "bound but the workers)")
      ->check(CLI::Range(std::int64_t(0), std::int64_t(1) << 40))
      ->capture_default_str();
  app.add_option("--encode-threads", o.encode_threads,
                 "frames encoded at once, on the compute threads (0: one per thread)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  app.add_option("--jpeg-encoder", jpeg_encoder,
                 "Where frames become JPEG: cpu (libjpeg-turbo, in bands), cuda (cinevol's coder on the rendering "
                 "GPU), nvjpeg (NVIDIA's, on the rendering GPU; refused at start where it cannot run) or auto (cuda "
                 "on a GPU server, else cpu)")
      ->check(CLI::IsMember({"auto", "cpu", "cuda", "nvjpeg"}))
      ->capture_default_str();
  app.add_option("--detached-session-seconds", o.detached_session_seconds,
                 "How long a session whose stream ended waits for a new one before it ends")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  app.add_option("--drain-seconds", o.drain_seconds, "On SIGTERM: notice to every stream, then exit within this")
      ->check(CLI::Range(0.5, 3600.0))
      ->capture_default_str();
  AddLimitOptions(app, o);
  app.add_option("--auth-tokens", o.auth_tokens,
                 "File of 'TOKEN PRINCIPAL [operator]' lines: calls must send 'authorization: Bearer TOKEN' "
                 "(default: open); SIGHUP reloads it");
  app.add_option("--tls-cert", o.tls.cert, "PEM certificate (chain) of the server: serve over TLS (with --tls-key)");
  app.add_option("--tls-key", o.tls.key, "PEM private key of --tls-cert");
  app.add_option("--tls-client-ca", o.tls.client_ca,
                 "PEM CA certificates: require client certificates signed by them (mutual TLS; the certificate's "
                 "CN names the caller)");
  app.add_flag("--insecure-no-auth", o.insecure_no_auth,
               "Allow listening beyond loopback with no --auth-tokens and no mutual TLS (anyone may call)");
  app.add_option("--advertise-address", o.advertise_address,
                 "HOST:PORT clients reach this server's sessions at, told in CreateSession's answer (behind a "
                 "load balancer: this instance's own name, e.g. a StatefulSet pod's; default: none, clients "
                 "stay on the address they used)")
      ->check(CLI::Validator(
          [](std::string& value) -> std::string {
            static const std::regex kHostPort(R"(^([A-Za-z0-9._-]{1,253}|\[[0-9A-Fa-f:.]{2,45}\]):[0-9]{1,5}$)");
            return std::regex_match(value, kHostPort) ? "" : "want HOST:PORT (a DNS name, IPv4 or [IPv6], and a port)";
          },
          "HOST:PORT"));
  app.add_option("--pacs", pacs.specs,
                 "NAME=URL of a DICOMweb service (PACS) clients may search and load series from, by NAME "
                 "(repeatable; docs/pacs.md)");
  app.add_option("--pacs-credentials", o.pacs_credentials,
                 "File of 'NAME basic USER:PASSWORD' or 'NAME bearer TOKEN' lines for the --pacs; SIGHUP reloads it");
  app.add_option("--pacs-auth", pacs.auth,
                 "'forward': every --pacs gets the caller's own bearer token (OAuth/OIDC-gated DICOMweb) instead of "
                 "stored credentials; 'NAME=forward': that PACS only (repeatable; docs/pacs.md)");
  app.add_option("--pacs-ca", pacs.ca_file, "PEM CA certificates to verify https PACS with (default: the system's)");
  app.add_option("--pacs-timeout-seconds", pacs.timeout_seconds, "The longest one request to a PACS may take")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--pacs-parallel-fetches", pacs.parallel_fetches, "Instances of one series fetched at once")
      ->check(CLI::Range(1, 32))
      ->capture_default_str();
  app.add_option("--pacs-max-series-mb", pacs.max_series_mb, "The most one retrieved series may bring, all instances")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  app.add_option("--port-file", o.port_file, "Write the port listened on to this file (useful with port 0)");
  app.add_option("--metrics-listen", o.metrics_listen,
                 "HOST:PORT to serve Prometheus metrics on, at /metrics (port 0: any free port, logged; "
                 "default: off)");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cinevol-server: remote volumetric path tracing with real-time denoising, over gRPC"};
  ServerOptions options;
  std::string backend = "auto";
  // auto: on a GPU server, cinevol's own coder on the GPU that renders each
  // frame (the host's cores stay free of JPEG under any load); libjpeg-turbo
  // on a CPU server (docs/performance.md, "JPEG on the GPU").
  std::string jpeg_encoder = "auto";
  std::string gpu_wait = "yield";
  bool verbose = false;
  PacsFlags pacs;
  AddOptions(app, options, backend, jpeg_encoder, gpu_wait, pacs);
  app.add_flag("-v,--verbose", verbose, "Log debug detail");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // a bad flag is bad input (2), as a bad listen address is
  }
  spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info);

  // SIGINT and SIGTERM end the server in order, SIGHUP reloads the token
  // and PACS credentials files; a thread waits for them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  try {
    options.backend = cinevol::ParseBackend(backend);
    options.jpeg_encoder = cinevol::ParseJpegEncoder(jpeg_encoder);
    options.gpu_wait = cinevol::ParseGpuWait(gpu_wait);
    options.pacs = pacs.Configs();
    cinevol::service::CheckListenPolicy(options.listen, !options.auth_tokens.empty(), options.tls.mutual(),
                                        options.insecure_no_auth);
    if (!cinevol::service::IsLoopbackListen(options.listen)) {
      if (options.insecure_no_auth && options.auth_tokens.empty() && !options.tls.mutual()) {
        spdlog::warn("!!! --insecure-no-auth: {} is reachable from other machines and ANYONE who can reach it may "
                     "load volumes and render, unauthenticated !!!",
                     options.listen);
      } else if (!options.auth_tokens.empty() && !options.tls.enabled()) {
        spdlog::warn("{} is reachable from other machines without TLS: bearer tokens travel in clear text; "
                     "give --tls-cert/--tls-key",
                     options.listen);
      }
    }
    cinevol::service::Server server(options);
    std::thread([&server, signals] {
      for (;;) {
        int signal = 0;
        sigwait(&signals, &signal);
        if (signal == SIGHUP) {
          cinevol::service::ReloadAllTokenFiles();
          server.ReloadPacsCredentials();
          continue;
        }
        server.Shutdown();
        return;
      }
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

// cinevol-bench calls: how promptly a server answers GetStatus and gRPC
// health while other clients create sessions on a large labelled volume
// (each creation frames the view over every label voxel). Without --server
// it writes the volume and its segmentation, starts a cinevol-server of its
// own on them (the CPU backend) and stops it afterwards.
#include <fmt/format.h>
#include <sys/utsname.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "bench.h"
#include "client.h"
#include "core/error.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "local_server.h"

namespace cinevol::bench {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

// The `q` quantile of `values` (nearest rank), 0 when empty.
double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const std::size_t rank = std::size_t(std::ceil(q * double(values.size())));
  return values[std::clamp<std::size_t>(rank, 1, values.size()) - 1];
}

// A raw little-endian 16-bit NRRD of n^3 voxels, 1 mm apart: `value(x, y, z)`.
template <class Value>
void WriteNrrd(const fs::path& file, int n, Value value) {
  std::ofstream out(file, std::ios::binary);
  out << fmt::format("NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: {0} {0} {0}\nspacings: 1 1 1\n"
                     "encoding: raw\nendian: little\n\n",
                     n);
  std::vector<std::uint16_t> row(n);
  for (int z = 0; z < n; ++z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) row[x] = value(x, y, z);
      out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size() * 2));
    }
  }
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

// A ball of soft tissue with a bony shell in air, and its segmentation: the
// ball cut into eight labelled octants (0 outside).
void WriteLabelledVolume(const fs::path& dir, int n) {
  const float c = 0.5f * float(n), r = 0.45f * float(n);
  auto radius = [&](int x, int y, int z) {
    const float dx = float(x) + 0.5f - c, dy = float(y) + 0.5f - c, dz = float(z) + 0.5f - c;
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  };
  WriteNrrd(dir / "volume.nrrd", n, [&](int x, int y, int z) -> std::uint16_t {
    const float d = radius(x, y, z);
    return d > r ? 0 : d > 0.9f * r ? 2400 : 1040;
  });
  WriteNrrd(dir / "labels.nrrd", n, [&](int x, int y, int z) -> std::uint16_t {
    if (radius(x, y, z) > r) return 0;
    return std::uint16_t(1 + (x * 2 / n) + 2 * (y * 2 / n) + 4 * (z * 2 / n));
  });
}

struct Sample {
  Clock::time_point start;
  double ms = 0;
};

std::string MachineDescription() {
  utsname u{};
  uname(&u);
  std::string cpu;
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);) {
    if (line.rfind("model name", 0) == 0) {
      cpu = line.substr(line.find(':') + 2);
      break;
    }
  }
  return fmt::format("{}, {} hardware threads, {} {}", cpu.empty() ? "unknown CPU" : cpu,
                     std::thread::hardware_concurrency(), u.sysname, u.release);
}

std::string Row(const std::string& what, const std::vector<double>& ms) {
  return fmt::format("| {} | {} | {:.1f} | {:.1f} | {:.1f} |\n", what, ms.size(), Quantile(ms, 0.5), Quantile(ms, 0.95),
                     ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end()));
}

}  // namespace

int RunCallsBench(const CallsBenchOptions& o) {
  std::unique_ptr<cli::LocalServer> local;
  ClientOptions options;
  options.address = o.server;
  options.token = o.token;
  options.call_timeout = std::chrono::seconds(600);
  std::string volume_id = o.volume;
  fs::path scratch;
  if (o.server.empty()) {
    scratch = fs::temp_directory_path() / fmt::format("cinevol-calls-bench-{}", ::getpid());
    fs::create_directories(scratch);
    std::fprintf(stderr, "writing a %d^3 volume and its segmentation to %s\n", o.size, scratch.c_str());
    WriteLabelledVolume(scratch, o.size);
    local = std::make_unique<cli::LocalServer>(
        "cpu", scratch / "server.log",
        std::vector<std::string>{"--data-root", scratch.string(), "--volume", "phantom:cube?size=8",
                                 "--max-sessions-per-principal", "64", "--encode-threads", "2"});
    options.address = local->address();
  }
  Client setup(options);
  if (local) {
    volume_id = setup.LoadVolume("volume.nrrd").id();
    setup.LoadLabels(volume_id, "labels.nrrd");
  }
  if (volume_id.empty()) throw InputError("--volume: needed with --server (a volume with a segmentation)");
  const v1::VolumeInfo info = setup.DescribeVolume(volume_id);
  if (!info.has_labels()) {
    std::fprintf(stderr, "warning: volume '%s' has no segmentation: creations scan no labels\n", volume_id.c_str());
  }

  // The prober: another client, on its own connection.
  Client prober(options);
  auto health = grpc::health::v1::Health::NewStub(prober.channel());
  auto check_health = [&] {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    grpc::health::v1::HealthCheckRequest request;
    grpc::health::v1::HealthCheckResponse response;
    Check(health->Check(&context, request, &response));
  };
  prober.Status();  // connections up before timing
  check_health();

  std::vector<std::unique_ptr<Client>> creators;
  for (int i = 0; i < o.clients; ++i) {
    creators.push_back(std::make_unique<Client>(options));
    creators.back()->Status();
  }
  v1::CreateSessionRequest request;
  request.set_volume_id(volume_id);
  request.mutable_viewport()->set_width(o.width);
  request.mutable_viewport()->set_height(o.height);

  std::mutex mu;
  std::vector<Sample> status_ms, health_ms, create_ms;
  std::atomic<bool> creating{true};
  std::atomic<int> failures{0};
  const Clock::time_point begin = Clock::now();
  // Each probe on its own thread: one that waits long does not hide the other.
  auto probe = [&](const std::function<void()>& call, std::vector<Sample>& samples) {
    return std::thread([&, call] {
      while (creating) {
        const Clock::time_point s = Clock::now();
        call();
        const double ms = Ms(Clock::now() - s);
        {
          std::lock_guard lock(mu);
          samples.push_back({s, ms});
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(o.interval_ms));
      }
    });
  };
  std::thread status_probe = probe([&] { prober.Status(); }, status_ms);
  std::thread health_probe = probe(check_health, health_ms);
  std::vector<std::thread> threads;
  for (auto& creator : creators) {
    threads.emplace_back([&, client = creator.get()] {
      for (int i = 0; i < o.creations; ++i) {
        try {
          const Clock::time_point t0 = Clock::now();
          const std::string id = client->CreateSession(request).session_id();
          const Clock::time_point t1 = Clock::now();
          {
            std::lock_guard lock(mu);
            create_ms.push_back({t0, Ms(t1 - t0)});
          }
          client->CloseSession(id);
        } catch (const std::exception& e) {
          ++failures;
          std::fprintf(stderr, "CreateSession: %s\n", e.what());
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();
  const Clock::time_point end = Clock::now();
  creating = false;
  status_probe.join();
  health_probe.join();

  // Only probes sent while creations were under way count.
  auto during = [&](const std::vector<Sample>& samples) {
    std::vector<double> ms;
    for (const Sample& s : samples) {
      if (s.start >= begin && s.start < end) ms.push_back(s.ms);
    }
    return ms;
  };
  std::vector<double> created;
  for (const Sample& s : create_ms) created.push_back(s.ms);
  const std::string table = fmt::format(
      "#### GetStatus and health while {} clients create sessions on a labelled volume\n\n"
      "`{}`\n\n"
      "Machine: {}. Volume '{}': {}x{}x{}, {} labels; {} creations of {}x{} sessions ({} failed), {:.1f} s in all.\n\n"
      "| call | calls | p50 ms | p95 ms | max ms |\n|---|---|---|---|---|\n{}{}{}\n",
      o.clients, o.command_line, MachineDescription(), volume_id, info.dims().x(), info.dims().y(), info.dims().z(),
      info.labels().names_size(), o.clients * o.creations, o.width, o.height, failures.load(), Ms(end - begin) / 1000.0,
      Row(fmt::format("CreateSession ({} clients at once)", o.clients), created),
      Row("GetStatus (another client)", during(status_ms)), Row("gRPC health (another client)", during(health_ms)));
  std::fputs(table.c_str(), stdout);
  if (!o.out.empty()) std::ofstream(o.out, std::ios::app) << table;
  local.reset();
  if (!scratch.empty()) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
  }
  return failures > 0 ? 1 : 0;
}

}  // namespace cinevol::bench

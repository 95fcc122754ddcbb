// `cinevol status --server ADDR`: the server's version, uptime, devices,
// sessions, volumes and encoder queue, as tables or proto3 JSON (--json).
#include <fmt/format.h>

#include "commands.h"
#include "connection_options.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct StatusOptions {
  ConnectionOptions connection;
  bool json = false;
};

void PrintDevices(const v1::ServerStatus& status) {
  std::vector<TextRow> rows{{"DEVICE", "SESSIONS", "VOLUMES", "MEMORY FREE", "MEMORY TOTAL", "FRAMES", "BUSY"}};
  for (const v1::DeviceStatus& d : status.devices()) {
    const bool gpu = d.memory_total_bytes() > 0;
    rows.push_back({d.name(), std::to_string(d.sessions()),
                    fmt::format("{} ({})", d.volume_copies(), Bytes(d.volume_copy_bytes())),
                    gpu ? Bytes(d.memory_free_bytes()) : "-", gpu ? Bytes(d.memory_total_bytes()) : "-",
                    std::to_string(d.frames_rendered()), fmt::format("{:.1f} s", d.busy_seconds())});
  }
  PrintTable(rows);
}

// Each volume's copies on the devices and how many renderers share each.
void PrintVolumeCopies(const v1::ServerStatus& status) {
  std::vector<TextRow> rows{{"VOLUME", "DEVICE", "COPY MEMORY", "RENDERERS"}};
  for (const v1::VolumeInfo& v : status.volumes()) {
    for (const v1::VolumeCopy& c : v.copies()) {
      rows.push_back({v.id(), c.device(), Bytes(c.bytes()), std::to_string(c.renderers())});
    }
  }
  if (rows.size() == 1) return fmt::print("no volume copies on the devices\n");
  PrintTable(rows);
}

// "RENDERING" for SessionStatus::RENDERING.
std::string StateName(v1::SessionStatus::State state) {
  return state == v1::SessionStatus::STATE_UNSPECIFIED ? "-" : v1::SessionStatus::State_Name(state);
}

void PrintSessions(const v1::ServerStatus& status) {
  if (status.sessions().empty()) {
    fmt::print("no sessions\n");
    return;
  }
  std::vector<TextRow> rows{
      {"SESSION", "OWNER", "VOLUME", "DEVICE", "VIEWPORT", "STATE", "SPP", "RENDERED", "SENT", "DROPPED"}};
  for (const v1::SessionStatus& s : status.sessions()) {
    rows.push_back({s.session_id(), s.owner().empty() ? "-" : s.owner(), s.volume_id(), s.device(),
                    fmt::format("{}x{}", s.viewport().width(), s.viewport().height()), StateName(s.state()),
                    std::to_string(s.accumulated_spp()), std::to_string(s.frames_rendered()),
                    std::to_string(s.frames_sent()), std::to_string(s.frames_dropped())});
  }
  PrintTable(rows);
}

void Run(const StatusOptions& o) {
  const v1::ServerStatus status = Connect(o.connection).Status();
  if (o.json) return PrintJson(status);
  fmt::print("cinevol-server {} at {}, up {:.0f} s; encoder: {} threads, {} frames queued\n\n", status.version(),
             o.connection.server, status.uptime_seconds(), status.encode_threads(), status.encode_queue());
  PrintDevices(status);
  fmt::print("\n");
  PrintSessions(status);
  fmt::print("\n");
  PrintVolumeTable({status.volumes().begin(), status.volumes().end()});
  fmt::print("\n");
  PrintVolumeCopies(status);
}

}  // namespace

void AddStatusCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("status", "A server's version, uptime, devices, sessions, volumes and encoder");
  auto o = std::make_shared<StatusOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_flag("--json", o->json, "Print the server's GetStatus answer as proto3 JSON (one object)");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

// `cinevol snapshot --server ADDR --out FILE [--session ID | --volume ID ...]`:
// a high-quality still from the server, as PNG (tone mapped) or EXR (linear).
#include <fmt/format.h>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "encode/image_codecs.h"
#include "io/scene_file.h"
#include "script_player.h"

namespace cinevol::cli {
namespace {

struct SnapshotOptions {
  ConnectionOptions connection;
  std::string out;
  std::string session;  // an existing session's current state; else a new session from the options below
  std::string volume, scene;
  std::string preset;  // empty: the volume's default preset
  int width = 1280, height = 720, spp = 256;
};

void Run(const SnapshotOptions& o) {
  const std::string ext = std::filesystem::path(o.out).extension().string();
  if (ext != ".png" && ext != ".exr") throw InputError(fmt::format("--out {}: use .png or .exr", o.out));
  Client client = Connect(o.connection);
  std::string session = o.session;
  if (session.empty()) {
    ScriptSession s;
    s.preset = o.preset;
    if (!o.scene.empty()) s.scene = LoadSceneFile(o.scene);
    s.viewport.set_width(o.width);
    s.viewport.set_height(o.height);
    session = client.CreateSession(SessionRequest(s, ResolveVolume(client, o.volume).id())).session_id();
  }
  v1::SnapshotRequest request;
  request.set_session_id(session);
  request.set_spp(o.spp);
  request.set_format(ext == ".exr" ? v1::EXR : v1::PNG);
  const v1::SnapshotResponse still = client.Snapshot(request);
  if (o.session.empty()) client.CloseSession(session);
  WriteFile(o.out, std::vector<std::uint8_t>(still.image().begin(), still.image().end()));
  fmt::print("wrote {}: {}x{}, {} spp, rendered in {:.2f} s\n", o.out, still.width(), still.height(), still.spp(),
             still.render_us() / 1e6);
}

}  // namespace

void AddSnapshotCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("snapshot", "A still from a server, to .png (tone mapped) or .exr (linear)");
  auto o = std::make_shared<SnapshotOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_option("--out", o->out, "Output image: .png or .exr")->required();
  cmd->add_option("--session", o->session, "Render this session's current state (default: a new session)");
  cmd->add_option("--volume", o->volume, "Volume id for a new session (default: the server's first)");
  cmd->add_option("--preset", o->preset, "Transfer-function preset for a new session (default: the volume's)");
  cmd->add_option("--scene", o->scene, "Scene file for a new session, instead of the preset");
  cmd->add_option("--width", o->width, "Width of a new session")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--height", o->height, "Height of a new session")->check(CLI::Range(1, 8192))->capture_default_str();
  cmd->add_option("--spp", o->spp, "Samples per pixel")->check(CLI::Range(1, 16384))->capture_default_str();
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

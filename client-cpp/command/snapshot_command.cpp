// `cinevol snapshot --server ADDR --out FILE [--session ID | --volume ID ...]`:
// a high-quality still from the server, as PNG (tone mapped) or EXR (linear).
#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <functional>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "encode/image_codecs.h"
#include "scene/scene_file.h"
#include "script_player.h"

namespace cinevol::cli {
namespace {

struct SnapshotOptions {
  ConnectionOptions connection;
  std::string out;
  std::string session;  // an existing session's current state; else a new session from the options below
  std::string volume, scene;
  std::string preset;  // empty: the volume's default preset
  std::string store_to;  // a PACS name: the still also goes there, into its volume's study
  int width = 1280, height = 720, spp = 256;
  double timeout = 0;  // seconds for the whole still; 0: none (progress keeps it going)
};

// Progress on stderr: one line rewritten in place on a terminal, else a line
// every 10% of the samples (logs stay short).
class ProgressPrinter {
 public:
  void operator()(const v1::SnapshotProgress& p) {
    if (tty_) {
      std::fprintf(stderr, "\rsnapshot: %s   ", DescribeProgress(p).c_str());
      std::fflush(stderr);
      shown_ = true;
      return;
    }
    const int tenth = p.spp() > 0 ? int(10 * p.spp_done() / p.spp()) : 0;
    if (tenth == last_tenth_) return;
    last_tenth_ = tenth;
    std::fprintf(stderr, "snapshot: %s\n", DescribeProgress(p).c_str());
  }
  ~ProgressPrinter() {
    if (shown_) std::fputc('\n', stderr);
  }

 private:
  const bool tty_ = isatty(fileno(stderr)) != 0;
  bool shown_ = false;
  int last_tenth_ = -1;
};

// The library's message names what ran out; this names the flags that change it.
[[noreturn]] void ThrowWithFlags(const RpcError& e) {
  if (e.code() != grpc::StatusCode::DEADLINE_EXCEEDED) throw e;
  std::string message = e.what();
  message.erase(0, message.find(": ") + 2);
  throw RpcError({grpc::StatusCode::DEADLINE_EXCEEDED,
                  message + " (--timeout S: seconds for the whole still, 0 for none; --spp, --width, --height)"});
}

// A session this command opened goes with it, whatever ended the still.
void CloseQuietly(Client& client, const std::string& session) {
  try {
    client.CloseSession(session);
  } catch (const RpcError&) {  // already ended (it was why the still failed), or the server is gone
  }
}

void Run(const SnapshotOptions& o) {
  const std::string ext = std::filesystem::path(o.out).extension().string();
  if (ext != ".png" && ext != ".exr") throw InputError(fmt::format("--out {}: use .png or .exr", o.out));
  Client client = Connect(o.connection);
  std::string session = o.session;
  if (session.empty()) {
    ScriptSession s;
    s.preset = o.preset;
    if (!o.scene.empty()) {
      s.scene = LoadSceneFile(o.scene);
      SayWhenUnlit(*s.scene, o.scene);
    }
    s.viewport.set_width(o.width);
    s.viewport.set_height(o.height);
    session = client.CreateSession(SessionRequest(s, ResolveVolume(client, o.volume).id())).session_id();
  }
  v1::SnapshotRequest request;
  request.set_session_id(session);
  request.set_spp(o.spp);
  request.set_format(ext == ".exr" ? v1::EXR : v1::PNG);
  request.set_store_to(o.store_to);
  cinevol::SnapshotOptions wait;
  wait.timeout = std::chrono::milliseconds(static_cast<long>(o.timeout * 1000));
  v1::SnapshotResponse still;
  try {
    ProgressPrinter printer;
    wait.on_progress = std::ref(printer);
    still = client.Snapshot(request, wait);
  } catch (const RpcError& e) {
    if (o.session.empty()) CloseQuietly(client, session);
    ThrowWithFlags(e);
  }
  if (o.session.empty()) client.CloseSession(session);
  WriteFile(o.out, std::vector<std::uint8_t>(still.image().begin(), still.image().end()));
  fmt::print("wrote {}: {}x{}, {} spp, rendered in {:.2f} s\n", o.out, still.width(), still.height(), still.spp(),
             still.render_us() / 1e6);
  if (still.has_stored()) {
    const v1::StoredObject& s = still.stored();
    fmt::print("stored in PACS '{}': study {}, series {}, instance {}\n", s.pacs(), s.study_uid(), s.series_uid(),
               s.sop_instance_uid());
  }
  if (still.has_presentation()) {
    const v1::StoredObject& p = still.presentation();
    fmt::print("its presentation state: series {}, instance {} (cinevol pacs load --pacs {} --presentation {})\n",
               p.series_uid(), p.sop_instance_uid(), p.pacs(), p.sop_instance_uid());
  }
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
  cmd->add_option("--store-to", o->store_to,
                  "A PACS the server names: store the still there too, as a DICOM Secondary Capture in the study "
                  "of the volume (one loaded with `cinevol pacs load`), its recipe inside, and a Volume Rendering "
                  "Volumetric Presentation State beside it");
  cmd->add_option("--spp", o->spp, "Samples per pixel")->check(CLI::Range(1, 16384))->capture_default_str();
  cmd->add_option("--timeout", o->timeout,
                  "Seconds the whole still may take (0: no limit; it ends anyway when the server reports no "
                  "progress for 2 minutes)")
      ->check(CLI::Range(0.0, 7.0 * 86400))
      ->capture_default_str();
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

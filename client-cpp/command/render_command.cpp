// `cinevol render (--scene S | --volume PATH [--preset P --width W --height H]) --out F [--spp N]
// [--error-target E] [--backend cpu|cuda] [--reconstruction trilinear|tricubic] [--remove-table]`: an
// offline still, refined as a session's view refines when it rests; no server involved.
#include <fmt/format.h>

#include "commands.h"
#include "offline_render.h"
#include "pipeline/frame_pipeline.h"

namespace cinevol::cli {
namespace {

struct RenderOptions {
  SceneSource source;
  std::string out, backend = "auto";
  std::string reconstruction;  // overrides the scene's
  int spp = 256;
  float error_target = kDefaultErrorTarget;
};

void Run(const RenderOptions& o) {
  CheckImageName(o.out);
  OfflineScene loaded = LoadOfflineScene(o.source);
  v1::Scene& scene = loaded.scene;
  if (!o.reconstruction.empty()) {
    scene.mutable_render()->set_reconstruction(o.reconstruction == "tricubic" ? v1::TRICUBIC : v1::TRILINEAR);
  }
  const int width = int(scene.render().width()), height = int(scene.render().height());
  const auto r = RenderToFile(std::move(loaded), o.spp, o.error_target, ParseBackend(o.backend), o.out);
  if (!r.table.empty()) fmt::print(stderr, "cinevol: remove table: {}\n", r.table);
  const std::string error = r.estimated_error >= 0 ? fmt::format(", estimated error {:.1f}%", 100 * r.estimated_error) : "";
  fmt::print("wrote {}: {}x{}, {} spp in {} frames{} on {}, {:.2f} s ({:.2f} Mpaths/s)\n", o.out, width, height,
             r.total_spp, r.frames, error, r.backend, r.seconds, r.paths_per_second / 1e6);
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "Render a scene or a volume to a refined still (.exr .pfm .png .jpg), no server");
  auto o = std::make_shared<RenderOptions>();
  AddSceneSource(cmd, o->source, SceneFlags::kWithPresetAndSize);
  cmd->add_option("--out", o->out, "Output image: .exr/.pfm linear HDR, .png/.jpg tone-mapped")->required();
  cmd->add_option("--spp", o->spp, "Samples per pixel at most (default 256)")->check(CLI::Range(1, 1 << 20));
  cmd->add_option("--error-target", o->error_target,
                  "Stop once the still's estimated relative error is at most this (default 0.02; 0: at --spp)")
      ->check(CLI::Range(0.0f, 1.0f));
  cmd->add_option("--backend", o->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd->add_option("--reconstruction", o->reconstruction, "trilinear or tricubic (default: the scene's)")
      ->check(CLI::IsMember({"trilinear", "tricubic"}));
  cmd->add_flag("--remove-table", o->source.remove_table,
                "Hide the CT's table (couch): the scene's labels.removeTable");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

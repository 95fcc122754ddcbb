// `cinevol render --scene S --out F [--spp N] [--backend cpu|cuda]
// [--reconstruction trilinear|tricubic] [--remove-table]`: an offline render of a scene file,
// no server involved.
#include <fmt/format.h>

#include "commands.h"
#include "scene/scene_file.h"
#include "offline_render.h"

namespace cinevol::cli {
namespace {

struct RenderOptions {
  std::string scene, out, backend = "auto";
  std::string reconstruction;  // overrides the scene's
  int spp = 0;
  bool remove_table = false;  // sets the scene's labels.removeTable
};

void Run(const RenderOptions& o) {
  v1::Scene scene = LoadSceneFile(o.scene);
  if (!o.reconstruction.empty()) {
    scene.mutable_render()->set_reconstruction(o.reconstruction == "tricubic" ? v1::TRICUBIC : v1::TRILINEAR);
  }
  if (o.remove_table) scene.mutable_labels()->set_remove_table(true);
  const int spp = o.spp > 0 ? o.spp : static_cast<int>(scene.render().spp());
  const auto r = RenderToFile(scene, {}, spp, ParseBackend(o.backend), o.out);
  if (scene.labels().remove_table()) fmt::print(stderr, "cinevol: remove table: {}\n", r.table);
  fmt::print("wrote {}: {}x{}, {} spp in {} frames on {}, {:.2f} s ({:.2f} Mpaths/s; loading {:.2f} s)\n", o.out,
             scene.render().width(), scene.render().height(), r.total_spp, r.frames, r.backend, r.seconds,
             r.paths_per_second / 1e6, r.load_seconds);
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "Render a scene file to an image (.exr .pfm .png .jpg), no server");
  auto o = std::make_shared<RenderOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (JSON of cinevol.v1.Scene)")->required();
  cmd->add_option("--out", o->out, "Output image: .exr/.pfm linear HDR, .png/.jpg tone-mapped")->required();
  cmd->add_option("--spp", o->spp, "Total samples per pixel (default: the scene's spp)")->check(CLI::Range(1, 1 << 20));
  cmd->add_option("--backend", o->backend, "auto, cpu or cuda")->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  cmd->add_option("--reconstruction", o->reconstruction, "trilinear or tricubic (default: the scene's)")
      ->check(CLI::IsMember({"trilinear", "tricubic"}));
  cmd->add_flag("--remove-table", o->remove_table, "Hide the CT's table (couch): the scene's labels.removeTable");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

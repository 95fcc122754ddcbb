// cinevol-viewer: connects to a cinevol-server (or starts one on the
// built-in phantom) and shows a session in a window (docs/viewer.md).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>

#include "core/error.h"
#include "viewer/viewer.h"

int main(int argc, char** argv) {
  CLI::App app{"cinevol-viewer: look at a volume on a cinevol-server, interactively"};
  cinevol::viewer::ViewerOptions o;
  cinevol::cli::AddConnectionOptions(&app, o.connection);
  app.get_option("--server")
      ->description(
          "Server address HOST:PORT, or a deployment's servers separated by commas (default: start a local server on "
          "the phantom)");
  std::string volume, load, upload, preset;
  auto* grant = app.add_option("--grant", o.grant,
                               "Watch a shared session by its grant's secret (cvg_..., from the owner's Share panel or "
                               "`cinevol share`) instead of creating one; needs --server");
  for (CLI::Option* option :
       {app.add_option("--volume", volume, "Volume id on the server (default: its first)"),
        app.add_option("--load", load, "Load this file or DICOM folder from the server's data roots first"),
        app.add_option("--upload", upload, "Upload this local volume file first")->check(CLI::ExistingFile),
        app.add_option("--preset", preset, "Transfer-function preset (default: the volume's default)"),
        app.add_option("--fuse", o.fuse.volume_id,
                       "A second volume on the server fused with the first (PET on CT): glowing in 3D, coloured over "
                       "the slices")}) {
    option->excludes(grant);  // the owner's session has its volume and scene
  }
  app.add_flag("--align-by-patient", o.fuse.align_by_patient,
               "With --fuse: place it by patient coordinates though the frames of reference differ")
      ->needs("--fuse");
  app.add_option("--backend", o.backend, "Backend of the local server: auto, cpu or cuda")
      ->check(CLI::IsMember({"auto", "cpu", "cuda"}));
  app.add_option("--script", o.script, "Play a session script (with UI actions), then exit")->check(CLI::ExistingFile);
  app.add_option("--screenshot", o.screenshot, "With --script: write the window to this PNG at the end");
  app.add_option("--width", o.width, "Window width")->check(CLI::Range(320, 8192))->capture_default_str();
  app.add_option("--height", o.height, "Window height")->check(CLI::Range(240, 8192))->capture_default_str();
  app.add_option("--max-seconds", o.max_seconds, "With --script: give up after this long")
      ->check(CLI::Range(1.0, 3600.0))
      ->capture_default_str();
  try {
    app.parse(argc, argv);
    o.local_server = app.get_option("--server")->count() == 0;
    o.session.volume = volume;
    o.session.load = load;
    o.session.upload = upload;
    o.session.preset = preset;
    if (!o.screenshot.empty() && o.script.empty()) throw cinevol::InputError("--screenshot needs --script");
    if (!o.grant.empty() && o.local_server) throw cinevol::InputError("--grant needs --server: where the session is");
    return cinevol::viewer::RunViewer(std::move(o));
  } catch (const CLI::ParseError& e) {
    // --help prints and exits 0; a bad flag is bad input, exit 2 as documented
    // (CLI11's own codes, 105 or 109, would say nothing to a script).
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const cinevol::RpcError& e) {
    std::fprintf(stderr, "cinevol-viewer: %s\n", e.what());
    return 3;
  } catch (const cinevol::InputError& e) {
    std::fprintf(stderr, "cinevol-viewer: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cinevol-viewer: internal error: %s\n", e.what());
    return 1;
  }
}

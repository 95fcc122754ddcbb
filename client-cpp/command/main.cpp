// cinevol: the thin client and tools (demo, render, info, ...).
#include <spdlog/spdlog.h>

#include <cstdio>

#include "commands.h"
#include "client.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{"cinevol: remote volumetric path tracing with real-time denoising"};
  app.require_subcommand(1);
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Log debug detail");
  app.parse_complete_callback([&] { spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info); });
  cinevol::cli::AddDemoCommand(app);
  cinevol::cli::AddViewCommand(app);
  cinevol::cli::AddRenderCommand(app);
  cinevol::cli::AddSliceCommand(app);
  cinevol::cli::AddInfoCommand(app);
  cinevol::cli::AddLoadtestCommand(app);
  cinevol::cli::AddPacsCommand(app);
  cinevol::cli::AddMeasurementsCommand(app);
  cinevol::cli::AddMovieCommand(app);
  cinevol::cli::AddPickCommand(app);
  cinevol::cli::AddPlayCommand(app);
  cinevol::cli::AddSnapshotCommand(app);
  cinevol::cli::AddVolumesCommand(app);
  cinevol::cli::AddStatusCommand(app);
  cinevol::cli::AddShareCommands(app);
  cinevol::cli::AddHealthCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // a command's own outcome (health: not serving, 1)
  } catch (const CLI::ParseError& e) {
    // --help prints and exits 0; a bad flag is bad input, exit 2 as documented
    // (CLI11's own codes, 105 or 109, would say nothing to a script).
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const cinevol::RpcError& e) {
    std::fprintf(stderr, "cinevol: %s\n", e.what());
    return 3;
  } catch (const cinevol::InputError& e) {
    std::fprintf(stderr, "cinevol: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cinevol: internal error: %s\n", e.what());
    return 1;
  }
  return 0;
}

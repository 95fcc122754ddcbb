// `cinevol movie --server ADDR --volume ID (--orbit DEGREES | --sweep AXIS | --phases) --seconds S --fps F
// --out F.mp4`: a session's view along a path (the camera about its target, a clip plane through the volume, or a
// time series' phases played in its own time),
// rendered by the server's RenderMovie (each frame refined to --spp samples, not the live stream's 2) and encoded
// there as H.264 in an MP4, written here; with --store-to, also stored as DICOM video in the volume's study.
#include <fmt/format.h>

#include <fstream>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "scene/scene_file.h"
#include "script_player.h"
#include "session_script.h"

namespace cinevol::cli {
namespace {

struct MovieOptions {
  ConnectionOptions connection;
  std::string volume, preset, scene, out, sweep;
  std::string store_to;  // a PACS: the movie also goes there as DICOM video, into its volume's study
  double orbit = 0;      // degrees about the view's up axis through its target
  bool orbit_given = false, phases = false;
  double seconds = 4;
  int fps = 25, width = 640, height = 480, spp = 64, crf = 18;
};

v1::SliceAxis SweepAxis(const std::string& name) {
  if (name == "x" || name == "sagittal") return v1::SAGITTAL;
  if (name == "y" || name == "coronal") return v1::CORONAL;
  if (name == "z" || name == "axial") return v1::AXIAL;
  throw InputError(fmt::format("--sweep {}: x (sagittal), y (coronal) or z (axial)", name));
}

v1::MovieRequest MovieRequest(const MovieOptions& o) {
  if (int(o.orbit_given) + int(!o.sweep.empty()) + int(o.phases) != 1) {
    throw InputError("give one path: --orbit DEGREES, --sweep AXIS or --phases");
  }
  v1::MovieRequest request;
  if (o.orbit_given) request.set_orbit_degrees(o.orbit);
  if (!o.sweep.empty()) request.set_sweep(SweepAxis(o.sweep));
  if (o.phases) request.set_phases(true);
  request.set_seconds(o.seconds);
  request.set_fps(std::uint32_t(o.fps));
  request.set_spp(std::uint32_t(o.spp));
  request.set_crf(std::uint32_t(o.crf));
  request.set_store_to(o.store_to);
  return request;
}

void Run(const MovieOptions& o) {
  v1::MovieRequest request = MovieRequest(o);
  Client client = Connect(o.connection);
  const v1::VolumeInfo volume = ResolveVolume(client, o.volume);
  if (o.phases && volume.phases() < 2) {
    throw InputError(
        fmt::format("--phases: volume '{}' holds one phase; a movie of phases needs a time series", volume.id()));
  }
  ScriptSession s;
  s.preset = o.preset;
  if (!o.scene.empty()) s.scene = LoadSceneFile(o.scene);
  s.viewport.set_width(o.width);
  s.viewport.set_height(o.height);
  const v1::CreateSessionResponse created = client.CreateSession(SessionRequest(s, volume.id()));
  request.set_session_id(created.session_id());
  v1::Movie movie;
  try {
    movie = client.RenderMovie(request, [](const v1::MovieProgress& p) {
      const double elapsed = p.elapsed_us() * 1e-6;
      fmt::print(stderr, "movie: frame {}/{}, {} spp each, {:.1f} s{}\n", p.frames_done(), p.frames(), p.spp(), elapsed,
                 p.frames_done() == 0 ? std::string()
                                      : fmt::format(", about {:.0f} s left",
                                                    elapsed / p.frames_done() * (p.frames() - p.frames_done())));
    });
  } catch (...) {
    try {
      client.CloseSession(created.session_id());
    } catch (const RpcError&) {  // the session already ended: what failed says why
    }
    throw;
  }
  client.CloseSession(created.session_id());
  std::ofstream(o.out, std::ios::binary) << movie.mp4();
  fmt::print("wrote {}: {} frames of {}x{} at {} frames/s ({:.1f} s), {} spp each, rendered in {:.1f} s\n", o.out,
             movie.frames(), movie.width(), movie.height(), movie.fps(), double(movie.frames()) / movie.fps(),
             movie.spp(), movie.render_us() * 1e-6);
  if (movie.has_stored()) {
    const v1::StoredObject& stored = movie.stored();
    fmt::print("stored in PACS '{}': study {}, series {}, instance {}\n", stored.pacs(), stored.study_uid(),
               stored.series_uid(), stored.sop_instance_uid());
  }
}

}  // namespace

void AddMovieCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("movie", "A movie of refined stills along a path, as H.264 in an MP4");
  auto o = std::make_shared<MovieOptions>();
  AddConnectionOptions(cmd, o->connection);
  cmd->add_option("--volume", o->volume, "Volume id (default: the server's first)");
  cmd->add_option("--preset", o->preset, "Transfer-function preset (default: the volume's)");
  cmd->add_option("--scene", o->scene, "Scene file to start from, instead of the preset");
  cmd->add_option("--orbit", o->orbit, "Turn the camera this many degrees about its target (360: a loop)")
      ->check(CLI::Range(-3600.0, 3600.0))
      ->each([o](const std::string&) { o->orbit_given = true; });
  cmd->add_option("--sweep", o->sweep, "Move a clip plane through the volume along x|y|z (sagittal|coronal|axial)");
  cmd->add_flag(
      "--phases", o->phases,
      "Play the volume's phases (a time series) in its own time, looping (10 phases/s where it has no times)");
  cmd->add_option("--seconds", o->seconds, "Length of the movie")
      ->check(CLI::Range(0.04, 600.0))
      ->capture_default_str();
  cmd->add_option("--fps", o->fps, "Frames per second")->check(CLI::Range(1, 60))->capture_default_str();
  cmd->add_option("--width", o->width, "Width, even")->check(CLI::Range(16, 4096))->capture_default_str();
  cmd->add_option("--height", o->height, "Height, even")->check(CLI::Range(16, 4096))->capture_default_str();
  cmd->add_option("--spp", o->spp, "Samples per pixel of each frame")
      ->check(CLI::Range(1, 16384))
      ->capture_default_str();
  cmd->add_option("--crf", o->crf, "H.264 constant quality: 0 lossless, 18 visually lossless, 51 worst")
      ->check(CLI::Range(0, 51))
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Output movie (.mp4)")->required();
  cmd->add_option("--store-to", o->store_to,
                  "A PACS the server names: store the movie there too, as DICOM video (MPEG-4 AVC), in the study of "
                  "the volume (one loaded with `cinevol pacs load`); at most 1920x1080 at 30 frames/s");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

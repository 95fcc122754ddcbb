// `cinevol movie --server ADDR --volume ID (--orbit DEGREES | --sweep AXIS | --phases) --seconds S --fps F
// --out F.mp4`: a session's stills, each refined to --spp samples (not the live stream's 2), along a path (the camera
// about its target, or a clip plane through the volume), encoded as H.264 in an MP4 (server/video/h264_writer.h).
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <cmath>
#include <numbers>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "image_files.h"
#include "scene/scene_file.h"
#include "script_player.h"
#include "session_script.h"
#include "vec3d.h"
#include "video/h264_writer.h"

namespace cinevol::cli {
namespace {

constexpr int kMaxFrames = 3600;  // two minutes at 30 frames/s: a movie, not a stream

struct MovieOptions {
  ConnectionOptions connection;
  std::string volume, preset, scene, out, sweep;
  std::string store_to;  // a PACS: the movie also goes there as DICOM video, into its volume's study
  double orbit = 0;  // degrees about the view's up axis through its target
  bool orbit_given = false, phases = false;
  double seconds = 4;
  int fps = 25, width = 640, height = 480, spp = 64, crf = 18;
};

// Rodrigues: `v` turned by `radians` about unit axis `k`.
Vec3d Turned(Vec3d v, Vec3d k, double radians) {
  const double c = std::cos(radians), s = std::sin(radians);
  return v * c + Cross(k, v) * s + k * (Dot(k, v) * (1 - c));
}

// The frame's camera on an orbit: the first frame's turned about the up axis through the target. A whole turn (or
// more) loops: its last frame stops one step short of the first.
v1::Camera OrbitCamera(const v1::Camera& start, double degrees, int frame, int frames) {
  const bool loop = std::abs(degrees) >= 360;
  const double t = frames == 1 ? 0 : double(frame) / double(loop ? frames : frames - 1);
  const Vec3d target = ToVec3d(start.target()), up = Normalized(ToVec3d(start.up()));
  v1::Camera camera = start;
  camera.set_view(v1::NAMED_VIEW_UNSPECIFIED);
  *camera.mutable_eye() = ToProto(target + Turned(ToVec3d(start.eye()) - target, up, degrees * t * std::numbers::pi / 180));
  return camera;
}

// The patient-axis extent of the volume: the smallest and largest coordinate of its voxel centres along `axis`.
std::pair<double, double> Extent(const v1::VolumeInfo& volume, int axis) {
  const Vec3d origin = ToVec3d(volume.origin_mm());
  double lo = origin[axis], hi = origin[axis];
  const double dims[3] = {double(volume.dims().x()), double(volume.dims().y()), double(volume.dims().z())};
  const double spacing[3] = {volume.spacing_mm().x(), volume.spacing_mm().y(), volume.spacing_mm().z()};
  for (int corner = 0; corner < 8; ++corner) {
    double at = origin[axis];
    for (int c = 0; c < 3; ++c) {
      const double direction = volume.direction_size() == 9 ? volume.direction(3 * axis + c) : (axis == c ? 1 : 0);
      if (corner & (1 << c)) at += direction * (dims[c] - 1) * spacing[c];
    }
    lo = std::min(lo, at);
    hi = std::max(hi, at);
  }
  return {lo, hi};
}

int SweepAxis(const std::string& name) {
  if (name == "x" || name == "sagittal") return 0;
  if (name == "y" || name == "coronal") return 1;
  if (name == "z" || name == "axial") return 2;
  throw InputError(fmt::format("--sweep {}: x (sagittal), y (coronal) or z (axial)", name));
}

// The frame's clipping on a sweep: a plane along the patient axis, from the volume's far end to its near one,
// keeping what lies beyond it, so the cut moves through the volume and the last frame shows none of it cut.
v1::Clipping SweepClipping(const v1::VolumeInfo& volume, int axis, int frame, int frames) {
  const auto [lo, hi] = Extent(volume, axis);
  const double t = frames == 1 ? 0 : double(frame) / double(frames - 1);
  Vec3d point = ToVec3d(volume.origin_mm()), normal{};
  point[axis] = hi - (hi - lo) * t;
  normal[axis] = 1;
  v1::Clipping clipping;
  v1::ClipPlane& plane = *clipping.add_planes();
  *plane.mutable_point() = ToProto(point);
  *plane.mutable_normal() = ToProto(normal);
  plane.set_cap(true);
  return clipping;
}

// The DICOM stream sent to the server, which stores it in the study of the session's volume.
void StoreMovie(Client& client, const MovieOptions& o, const std::string& session_id,
                const std::filesystem::path& stream_file, int frames) {
  std::ifstream in(stream_file, std::ios::binary);
  const std::string h264{std::istreambuf_iterator<char>(in), {}};
  std::filesystem::remove(stream_file);
  v1::StoreMovieChunk::Header header;
  header.set_session_id(session_id);
  header.set_pacs(o.store_to);
  header.set_width(std::uint32_t(o.width));
  header.set_height(std::uint32_t(o.height));
  header.set_fps(std::uint32_t(o.fps));
  header.set_frames(std::uint32_t(frames));
  header.set_description(o.orbit_given ? fmt::format("orbit {:g} deg", o.orbit) : "sweep " + o.sweep);
  const v1::StoredObject stored = client.StoreMovie(header, h264);
  fmt::print("stored in PACS '{}': study {}, series {}, instance {}\n", stored.pacs(), stored.study_uid(),
             stored.series_uid(), stored.sop_instance_uid());
}

void Run(const MovieOptions& o) {
  if (int(o.orbit_given) + int(!o.sweep.empty()) + int(o.phases) != 1) {
    throw InputError("give one path: --orbit DEGREES, --sweep AXIS or --phases");
  }
  const int frames = int(std::lround(o.seconds * o.fps));
  if (frames < 1 || frames > kMaxFrames) {
    throw InputError(fmt::format("--seconds {} at --fps {} is {} frames; 1 to {}", o.seconds, o.fps, frames, kMaxFrames));
  }
  const int sweep_axis = o.sweep.empty() ? -1 : SweepAxis(o.sweep);
  VideoSettings video{o.width, o.height, o.fps, o.crf};
  Client client = Connect(o.connection);
  const v1::VolumeInfo volume = ResolveVolume(client, o.volume);
  if (o.phases) {
    throw InputError(fmt::format("--phases: volume '{}' holds one phase; a movie of phases needs a time series",
                                 volume.id()));
  }
  H264Writer writer(o.out, VideoContainer::kMp4, video);  // checks the size and rate before a still is rendered
  // For DICOM: the same frames as an H.264 byte stream within level 4.1, the one DICOM's transfer syntax names.
  const std::filesystem::path stream_file = o.out + ".h264";
  std::optional<H264Writer> dicom_stream;
  if (!o.store_to.empty()) {
    VideoSettings dicom = video;
    dicom.dicom_level = true;
    dicom_stream.emplace(stream_file, VideoContainer::kAnnexB, dicom);
  }
  ScriptSession s;
  s.preset = o.preset;
  if (!o.scene.empty()) s.scene = LoadSceneFile(o.scene);
  s.viewport.set_width(o.width);
  s.viewport.set_height(o.height);
  const v1::CreateSessionResponse created = client.CreateSession(SessionRequest(s, volume.id()));
  const auto start = std::chrono::steady_clock::now();
  try {
    for (int frame = 0; frame < frames; ++frame) {
      v1::SessionEvent event;
      if (o.orbit_given) *event.mutable_camera() = OrbitCamera(created.scene().camera(), o.orbit, frame, frames);
      if (sweep_axis >= 0) *event.mutable_clipping() = SweepClipping(volume, sweep_axis, frame, frames);
      client.SendEvents(created.session_id(), {event});
      v1::SnapshotRequest request;
      request.set_session_id(created.session_id());
      request.set_spp(std::uint32_t(o.spp));
      const v1::SnapshotResponse still = client.Snapshot(request);
      const RgbImage image = DecodePngImage(still.image());
      writer.Add(image.rgb);
      if (dicom_stream) dicom_stream->Add(image.rgb);
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      fmt::print(stderr, "movie: frame {}/{}, {} spp, {:.1f} s, about {:.0f} s left\n", frame + 1, frames, still.spp(),
                 elapsed, elapsed / (frame + 1) * (frames - frame - 1));
    }
    writer.Finish();
    if (dicom_stream) dicom_stream->Finish();
  } catch (...) {
    std::filesystem::remove(stream_file);
    try {
      client.CloseSession(created.session_id());
    } catch (const RpcError&) {  // the session already ended: what failed says why
    }
    throw;
  }
  if (dicom_stream) StoreMovie(client, o, created.session_id(), stream_file, frames);
  client.CloseSession(created.session_id());
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print("wrote {}: {} frames of {}x{} at {} frames/s ({:.1f} s), {} spp each, rendered in {:.1f} s\n", o.out,
             writer.frames(), o.width, o.height, o.fps, double(writer.frames()) / o.fps, o.spp, elapsed);
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
  cmd->add_flag("--phases", o->phases, "Play the volume's phases (a time series)");
  cmd->add_option("--seconds", o->seconds, "Length of the movie")->check(CLI::Range(0.04, 600.0))->capture_default_str();
  cmd->add_option("--fps", o->fps, "Frames per second")->check(CLI::Range(1, 60))->capture_default_str();
  cmd->add_option("--width", o->width, "Width, even")->check(CLI::Range(16, 4096))->capture_default_str();
  cmd->add_option("--height", o->height, "Height, even")->check(CLI::Range(16, 4096))->capture_default_str();
  cmd->add_option("--spp", o->spp, "Samples per pixel of each frame")->check(CLI::Range(1, 16384))->capture_default_str();
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

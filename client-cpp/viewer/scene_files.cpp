// Snapshots and scene files.
#include "viewer/scene_files.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <charconv>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "image_files.h"
#include "session_script.h"

namespace cinevol::viewer {
namespace {

namespace fs = std::filesystem;

// A phantom's source ("phantom:head?size=64&spacing=2") as the scene file's
// Phantom, so that a saved phantom renders offline as a phantom.
v1::Phantom PhantomOf(const std::string& spec) {
  v1::Phantom phantom;
  const std::string name = spec.substr(0, spec.find('?'));
  phantom.set_kind(name == "cube" ? v1::Phantom::CUBE : name == "sphere" ? v1::Phantom::SPHERE : v1::Phantom::HEAD);
  std::string rest = name.size() < spec.size() ? spec.substr(name.size() + 1) : "";
  while (!rest.empty()) {
    const std::string item = rest.substr(0, rest.find('&'));
    rest.erase(0, std::min(rest.size(), item.size() + 1));
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = item.substr(0, eq), text = item.substr(eq + 1);
    float value = 0;
    if (std::from_chars(text.data(), text.data() + text.size(), value).ec != std::errc()) continue;
    if (key == "size") phantom.set_size(std::uint32_t(value));
    if (key == "spacing") phantom.set_spacing(value);
    if (key == "value") phantom.set_value(value);
    if (key == "background") phantom.set_background(value);
    if (key == "radius") phantom.set_radius(value);
  }
  return phantom;
}

// Where the volume came from, as a scene file names it: a phantom stays a
// phantom, a folder a DICOM folder, anything else a file (edit it where the
// server's path is not this machine's).
v1::VolumeSource SourceOf(const std::string& source) {
  v1::VolumeSource out;
  constexpr std::string_view kPhantom = "phantom:";
  std::error_code ec;
  if (source.rfind(kPhantom, 0) == 0) {
    *out.mutable_phantom() = PhantomOf(source.substr(kPhantom.size()));
  } else if (fs::is_directory(source, ec)) {
    out.set_dicom_folder(source);
  } else {
    out.set_file(source);
  }
  return out;
}

// A scene file read as every cinevol program reads one (defaults filled,
// every field checked, relative paths against its folder): through the
// session scripts' reader, whose "scene" line holds that rule for clients.
v1::Scene ReadSceneFile(const std::string& path) {
  google::protobuf::Value name;
  name.set_string_value(fs::absolute(path).string());
  std::string quoted;
  google::protobuf::util::MessageToJsonString(name, &quoted);
  try {
    return *cli::ParseScript(R"({"session": {"scene": )" + quoted + "}}", path).session.scene;
  } catch (const InputError& e) {
    const std::string what = e.what();
    constexpr std::string_view kLine = "session.scene: ";  // the script's words around the file's
    const std::size_t at = what.find(kLine);
    throw InputError(at == std::string::npos ? what : what.substr(at + kLine.size()));
  }
}

}  // namespace

void SetLabelsFor(ShownSession& session, const std::optional<v1::VolumeInfo>& volume, const v1::Labels& labels) {
  if (!volume) return;
  if (volume->has_labels()) {
    session.SetLabels(labels);
  } else if (volume->table().voxels() > 0) {
    v1::Labels table;
    table.set_remove_table(labels.remove_table());
    session.SetLabels(table);
  }
}

void SceneFiles::Snapshot(const std::string& path, int spp) {
  const std::string ext = fs::path(path).extension().string();
  if (ext != ".png" && ext != ".exr") {
    context_.notice = fmt::format("snapshot {}: use .png or .exr", path);
    return;
  }
  v1::SnapshotRequest request;
  request.set_session_id(link_.session_id());
  request.set_spp(spp);
  request.set_format(ext == ".exr" ? v1::EXR : v1::PNG);
  context_.notice = fmt::format("rendering {} at {} spp...", path, spp);
  // No deadline: a still on a CPU server takes minutes. The line under the
  // panels follows its progress; closing the window cancels it.
  link_.connection().Request(
      [this, request, path, stopping = &link_.connection().stopping()](Client& client) {
        SnapshotOptions wait;
        wait.cancel = stopping;
        wait.on_progress = [this, path](const v1::SnapshotProgress& p) {
          context_.ui.Later(
              [this, path, text = DescribeProgress(p)] { context_.notice = fmt::format("rendering {}: {}", path, text); });
        };
        const v1::SnapshotResponse still = client.Snapshot(request, wait);
        WriteBytesFile(path, still.image());
        context_.ui.Later([this, path, still] {
          context_.notice = fmt::format("wrote {} ({}x{}, {} spp, {:.1f} s)", path, still.width(), still.height(),
                                        still.spp(), still.render_us() / 1e6);
        });
      },
      [this, path](const std::string& error) {
        if (!error.empty()) {
          context_.ui.Later([this, path, error] { context_.notice = fmt::format("snapshot {}: {}", path, error); });
        }
      });
}

void SceneFiles::Movie(const std::string& path, v1::MovieRequest request) {
  if (fs::path(path).extension() != ".mp4") {
    context_.notice = fmt::format("movie {}: use .mp4", path);
    return;
  }
  request.set_session_id(link_.session_id());
  context_.notice = fmt::format("recording {} at {} spp a frame...", path, request.spp());
  link_.connection().Request(
      [this, request, path](Client& client) {
        const v1::Movie movie = client.RenderMovie(request, [this, path](const v1::MovieProgress& p) {
          context_.ui.Later([this, path, p] {
            context_.notice = fmt::format("recording {}: frame {} of {}", path, p.frames_done(), p.frames());
          });
        });
        WriteBytesFile(path, movie.mp4());
        context_.ui.Later([this, path, frames = movie.frames(), us = movie.render_us()] {
          context_.notice = fmt::format("wrote {} ({} frames, {:.1f} s to render)", path, frames, us / 1e6);
        });
      },
      [this, path](const std::string& error) {
        if (!error.empty()) {
          context_.ui.Later([this, path, error] { context_.notice = fmt::format("movie {}: {}", path, error); });
        }
      });
}

void SceneFiles::Save(const std::string& path) {
  // The session's scene as the server resolved it: the camera as numbers, the
  // transfer function as points (with its preset's name), and the rest.
  v1::Scene scene = link_.shown().scene();
  const v1::Labels& labels = scene.labels();
  if (labels.styles_size() == 0 && !labels.has_show_unlisted() && !labels.remove_table()) scene.clear_labels();
  scene.mutable_render()->set_width(link_.viewport_width());
  scene.mutable_render()->set_height(link_.viewport_height());
  if (const auto& volume = link_.volume()) *scene.mutable_volume() = SourceOf(volume->source());
  // One frame for the whole file, as its clipping and measurements.
  if (const auto placement = link_.placement()) MoveSceneToPatient(scene, *placement);
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = true;
  std::string json;
  google::protobuf::util::MessageToJsonString(scene, &json, print);
  std::ofstream out(path);
  out << json;
  context_.notice = out ? fmt::format("saved the scene to {}", path) : fmt::format("cannot write {}", path);
}

void SceneFiles::Open(const std::string& path) {
  v1::Scene scene;
  try {
    scene = ReadSceneFile(path);
  } catch (const std::exception& e) {
    context_.notice = e.what();
    return;
  }
  const auto placement = link_.placement();
  if (placement) MoveSceneToVolumeCentred(scene, *placement);  // the session's frame for camera and lights
  const std::optional<v1::VolumeInfo>& volume = link_.volume();
  ShownSession& session = link_.shown();
  const v1::Camera& camera = scene.camera();
  if (camera.has_eye() && camera.has_target() && scene.frame() != v1::PATIENT_LPS) {
    session.SetCamera(CameraOf(camera, session.camera()));
  } else if (camera.view() != v1::NAMED_VIEW_UNSPECIFIED) {
    v1::SessionEvent e;  // the view alone: the server frames what the scene shows
    e.mutable_camera()->set_view(camera.view());
    session.Send(std::move(e));
  }
  v1::TransferFunction tf = scene.transfer_function();
  if (tf.points().empty() && tf.preset().empty() && volume) tf.set_preset(volume->default_preset());
  session.SetTransferFunction(tf);  // a preset without points: the server fits it to this volume
  // A file without lights keeps the lights on screen (sending none would leave the volume black).
  if (scene.lights_size() > 0) session.SetLights(scene.lights());
  v1::RenderSettings render;
  render.set_spp(scene.render().spp());
  render.set_max_bounces(scene.render().max_bounces());
  render.set_reconstruction(scene.render().reconstruction() == v1::TRICUBIC ? v1::TRICUBIC : v1::TRILINEAR);
  session.SetRender(render);
  session.SetClipping(scene.clipping());
  SetLabelsFor(session, volume, scene.labels());
  session.SetMeasurements({scene.measurements().begin(), scene.measurements().end()});
  if (scene.has_time() && volume && volume->phases() > 1) session.SetTime(scene.time());  // as Save wrote it
  // The second volume is the session's from its start: a file's shows over that same one only.
  const bool other_fusion = scene.has_fusion() && scene.fusion().volume_id() != session.scene().fusion().volume_id();
  if (scene.has_fusion() && !other_fusion) session.SetFusion(scene.fusion());
  const bool styles = scene.labels().styles_size() > 0 || scene.labels().has_show_unlisted();
  context_.notice = styles && !(volume && volume->has_labels())
                        ? fmt::format("opened {}; its label styles wait for a segmentation of this volume", path)
                        : fmt::format("opened {}", path);
  if (scene.lights_size() == 0) context_.notice += " (it has no lights: the lights stay as they were)";
  if (other_fusion) {
    context_.notice += fmt::format(" (its second volume {} needs a session started with it: --fuse)",
                                   scene.fusion().volume_id());
  }
}

}  // namespace cinevol::viewer

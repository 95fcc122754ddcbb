// The viewer's UI thread: the SDL loop, frames onto the screen, mouse and
// keys, session scripts and screenshots.
#include "viewer/viewer_app.h"

#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <imgui.h>
#include <imgui_impl_sdl.h>
#include <imgui_impl_sdlrenderer.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include "core/error.h"
#include "encode/image_codecs.h"
#include "io/volume_loader.h"
#include "scene/presets.h"
#include "scene/scene_file.h"
#include "scene/scene_frame.h"
#include "script_player.h"
#include "viewer/transfer_edits.h"

namespace cinevol::viewer {
namespace {

constexpr float kPanelWidth = 330;  // logical pixels
constexpr float kClickSlop = 3;     // logical pixels a press may move and still be a click
constexpr auto kResizeSettle = std::chrono::milliseconds(250);
constexpr auto kFramePeriod = std::chrono::milliseconds(8);  // at most ~120 displayed frames a second
constexpr double kSettleSeconds = 1.0;  // scripts: frames after the last event before the screenshot

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

ValueHistogram ToHistogram(const v1::ValueHistogram& proto) {
  ValueHistogram h;
  h.min_value = proto.min_value();
  h.max_value = proto.max_value();
  h.counts.assign(proto.counts().begin(), proto.counts().end());
  h.counts.resize(ValueHistogram::kBins, 0);
  return h;
}

// Refused, or the server cannot be reached (retrying).
bool Broken(LinkState s) { return s == LinkState::kFailed || s == LinkState::kReconnecting; }

// What a script's line says of a series: no descriptions, which a site may
// fill with anything.
google::protobuf::Value SeriesValue(const v1::SeriesSummary& s) {
  google::protobuf::Value v;
  auto& fields = *v.mutable_struct_value()->mutable_fields();
  fields["seriesUid"] = TextValue(s.series_uid());
  fields["modality"] = TextValue(s.modality());
  fields["instances"] = NumberValue(double(s.instance_count()));
  return v;
}

// The series a load without a choice takes, as `cinevol pacs load` does: the most instances.
std::string LargestSeries(const std::vector<v1::SeriesSummary>& series) {
  const auto largest = std::max_element(series.begin(), series.end(), [](const auto& a, const auto& b) {
    return a.instance_count() < b.instance_count();
  });
  return largest == series.end() ? std::string() : largest->series_uid();
}

}  // namespace

// ---------------------------------------------------------------- stats

double ViewerStats::Fps() const { return double(displayed.size()); }

double ViewerStats::LatencyPercentile(double q) const {
  if (latency_ms.empty()) return NAN;
  std::vector<double> v(latency_ms.begin(), latency_ms.end());
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * double(v.size())))];
}

double ViewerStats::BytesPerSecond() const {
  double sum = 0;
  for (const auto& [at, n] : bytes) sum += double(n);
  return sum;
}

// ------------------------------------------------------------ lifecycle

App::App(ViewerOptions o) : options(std::move(o)) {
  if (!options.script.empty()) {
    script_ = cli::LoadScript(options.script);
    // The script's session line says what it names; the command line the rest.
    cli::ScriptSession& s = script_->session;
    const bool names_volume = !s.volume.empty() || !s.load.empty() || !s.upload.empty();
    if (!names_volume)
      s.volume = options.session.volume, s.load = options.session.load, s.upload = options.session.upload;
    if (s.preset.empty() && !s.scene) s.preset = options.session.preset;
    options.session = s;
    for (const cli::ScriptStep& step : script_->steps) {
      if (!step.ui.empty()) RunUiAction(step.ui, -step.line);  // a dry run: checks every action
    }
  }
  OpenDisplay();               // first: without one there is nothing to start a server for
  if (options.local_server) {  // before the window: a window that waits for it would not answer
    const auto log = std::filesystem::temp_directory_path() / fmt::format("cinevol-viewer-{}.log", getpid());
    std::fprintf(stderr, "cinevol-viewer: starting a local cinevol-server (log: %s)...\n", log.c_str());
    local_server = std::make_unique<cli::LocalServer>(options.backend, log);
    options.connection.server = local_server->address();
  }
  window_ = SDL_CreateWindow("cinevol-viewer", SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, options.width,
                             options.height, SDL_WINDOW_RESIZABLE | SDL_WINDOW_ALLOW_HIGHDPI);
  if (!window_) throw InputError(fmt::format("cannot open a window: {}", SDL_GetError()));
  renderer_ = SDL_CreateRenderer(window_, -1, SDL_RENDERER_ACCELERATED);
  if (!renderer_) renderer_ = SDL_CreateRenderer(window_, -1, SDL_RENDERER_SOFTWARE);
  if (!renderer_) throw InputError(fmt::format("cannot draw in the window: {}", SDL_GetError()));
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // the layout is the program's, not a file's
  ImGui::StyleColorsDark();
  ImGui_ImplSDL2_InitForSDLRenderer(window_);
  ImGui_ImplSDLRenderer_Init(renderer_);
  Layout();
}

void App::OpenDisplay() {
  if (SDL_Init(SDL_INIT_VIDEO) != 0) throw InputError(fmt::format("cannot open a window: {}", SDL_GetError()));
  // Without a display SDL falls back to drivers that draw nowhere: the
  // window would run unseen for ever. Only a user who asks for one gets it.
  const std::string driver = SDL_GetCurrentVideoDriver() ? SDL_GetCurrentVideoDriver() : "";
  const bool windowless = driver == "offscreen" || driver == "dummy" || driver == "evdev";
  if (windowless && !std::getenv("SDL_VIDEODRIVER")) {
    throw InputError(
        "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are not set): run it in a desktop session or "
        "over ssh -X; for a script without a screen, use xvfb-run (or SDL_VIDEODRIVER=offscreen)");
  }
}

App::~App() {
  connection.reset();  // closes the session before the local server stops
  retired_.clear();    // joins the threads closing earlier sessions
  local_server.reset();
  ImGui_ImplSDLRenderer_Shutdown();
  ImGui_ImplSDL2_Shutdown();
  ImGui::DestroyContext();
  if (texture_) SDL_DestroyTexture(texture_);
  for (SlicePane& pane : reading.panes) {
    if (pane.texture) SDL_DestroyTexture(pane.texture);
  }
  if (renderer_) SDL_DestroyRenderer(renderer_);
  if (window_) SDL_DestroyWindow(window_);
  SDL_Quit();
}

void App::Connect() {
  ConnectionSettings settings{cli::ToClientOptions(options.connection), options.session, options.grant};
  // The session starts at the size the window shows it.
  viewport_w_ = Pixels(frame_area.w);
  viewport_h_ = Pixels(frame_area.h);
  settings.session.viewport.set_width(viewport_w_);
  settings.session.viewport.set_height(viewport_h_);
  connection = std::make_unique<Connection>(std::move(settings));
  if (Watching()) {
    sharing.me = GuessedHolderName(options.grant);  // until the pointer's echo names it
  } else {
    ListPacs();  // each connection asks: the panel shows only where the server names a PACS
  }
}

int App::Run() {
  Connect();
  while (!quit_) {
    const Clock::time_point frame_start = Clock::now();
    PumpSdlEvents();
    std::vector<std::function<void()>> later;
    {
      std::lock_guard lock(later_mu_);
      later.swap(later_);
    }
    for (auto& f : later) f();
    AdoptSession();
    FollowSharing();
    if (std::string warning = connection->TakeWarning(); !warning.empty()) notice = warning;
    const bool new_frame = TakeFrame();
    RunScript();
    ResizeViewportWhenSettled();
    if (camera_dirty_ && Drives()) {  // one camera event per displayed frame
      v1::SessionEvent e;
      *e.mutable_camera() = ToProto(camera);
      Post(std::move(e));
      camera_dirty_ = false;
    }
    SharePointer();

    ImGui_ImplSDLRenderer_NewFrame();
    ImGui_ImplSDL2_NewFrame();
    ImGui::NewFrame();
    Layout();
    DrawPanels(*this);
    DrawReadingOverlay(*this);
    DrawSharingOverlay(*this);
    if (panels.stats) DrawStatsOverlay(*this);
    DrawStatusBanner(*this, connection->status());
    ImGui::Render();
    SDL_SetRenderDrawColor(renderer_, 24, 26, 30, 255);
    SDL_RenderClear(renderer_);
    DrawFrame();
    DrawSlices();
    ImGui_ImplSDLRenderer_RenderDrawData(ImGui::GetDrawData());
    for (const std::string& file : screenshots_) WriteScreenshot(file);
    screenshots_.clear();
    if (script_ && ScriptDone()) {
      if (!options.screenshot.empty()) WriteScreenshot(options.screenshot);
      quit_ = true;
    }
    SDL_RenderPresent(renderer_);
    if (new_frame) {  // the UI thread's cost of showing it: upload, panels, drawing, present
      const double loop_ms = Ms(Clock::now() - frame_start);
      stats.draw_ms = loop_ms - stats.upload_ms;
      if (script_) stats.all_ui_ms.push_back(loop_ms);
    }
    std::this_thread::sleep_until(frame_start + kFramePeriod);
  }
  if (script_) PrintSummary();
  return exit_code_;
}

// ----------------------------------------------------------- the session

void App::Later(std::function<void()> f) {
  std::lock_guard lock(later_mu_);
  later_.push_back(std::move(f));
}

void App::AdoptSession() {
  const std::optional<v1::CreateSessionResponse> s = connection->session();
  if (!s || s->session_id() == session_id) return;
  const bool restore =
      !session_id.empty() && volume && connection->volume() && volume->id() == connection->volume()->id();
  session_id = s->session_id();
  stats.last_frame_id = 0;
  // A new session has no grants: a restarted server forgot them.
  SharingState fresh;
  fresh.form = sharing.form;  // the panel's fields stay as typed
  fresh.generation = sharing.generation + 1;
  sharing = std::move(fresh);
  LearnOwnName();
  // The server lost our session: the connection created it again from the
  // server's last state of it (Connection::carried_), which is what we show.
  if (restore) return;
  volume = connection->volume();
  camera = ViewCamera{};
  ShowScene(s->scene());
  home = camera;
  stream = options.session.stream;
  reading.measurements.assign(s->scene().measurements().begin(), s->scene().measurements().end());
}

void App::ShowScene(const v1::Scene& scene) {
  // A named view without its eye (an event's) turns about the camera shown.
  const v1::Camera& c = scene.camera();
  const bool named = c.view() != v1::NAMED_VIEW_UNSPECIFIED && !c.has_eye();
  camera = named && volume ? NamedView(camera, c.view(), volume->direction()) : FromProto(c, camera);
  transfer = scene.transfer_function();
  if (transfer.points().empty() && volume) {
    const std::string preset = transfer.preset().empty() ? volume->default_preset() : transfer.preset();
    transfer = MakePreset(preset, AutoWindow(ToHistogram(volume->histogram())));
  }
  lights.mutable_lights()->CopyFrom(scene.lights());
  render = scene.render();
  clipping = scene.clipping();
  labels = scene.labels();
}

void App::Post(v1::SessionEvent event) {
  if (Drives()) connection->Post(std::move(event));
}

void App::SendTransferFunction() {
  v1::SessionEvent e;
  *e.mutable_transfer_function() = transfer;
  Post(std::move(e));
}

void App::SendClipping() {
  v1::SessionEvent e;
  *e.mutable_clipping() = clipping;
  Post(std::move(e));
}

void App::SendLights() {
  v1::SessionEvent e;
  *e.mutable_lights() = lights;
  Post(std::move(e));
}

void App::SendRender() {
  v1::SessionEvent e;
  e.mutable_render()->set_spp(render.spp());
  e.mutable_render()->set_max_bounces(render.max_bounces());
  e.mutable_render()->set_reconstruction(render.reconstruction() == v1::TRICUBIC ? v1::TRICUBIC : v1::TRILINEAR);
  Post(std::move(e));
}

void App::SendLabels() {
  if (!volume) return;
  v1::SessionEvent e;
  if (volume->has_labels()) {
    *e.mutable_labels() = labels;
  } else if (volume->table().voxels() > 0) {
    e.mutable_labels()->set_remove_table(labels.remove_table());  // styles wait for a segmentation
  } else {
    return;  // nothing the session can style
  }
  Post(std::move(e));
}

void App::SendStream() {
  v1::SessionEvent e;
  *e.mutable_stream() = stream;
  Post(std::move(e));
}

void App::SendCamera() { camera_dirty_ = true; }

void App::ChoosePreset(const std::string& name) {
  // Without the volume (another's session) the server fits the preset.
  transfer.Clear();
  transfer.set_preset(name);
  if (volume) transfer = MakePreset(name, AutoWindow(ToHistogram(volume->histogram())));
  editor = {};
  SendTransferFunction();
}

void App::SwitchVolume(const std::string& id) {
  options.session.volume = id;
  options.session.load.clear();
  options.session.upload.clear();
  options.session.preset.clear();  // the new volume's default
  options.session.scene.reset();
  // Closing the old session may wait on the network: not on this thread.
  retired_.emplace_back([old = std::move(connection)]() mutable { old.reset(); });
  session_id.clear();
  volume.reset();
  stats.last_frame_id = 0;  // a script's settle waits for the new session's first frame
  // Calls queued on the old connection never run and those running are not
  // heard of: nothing of the panel waits for them.
  ++pacs.generation;
  pacs.busy = 0;
  pacs.opening = false;
  pacs.progress.reset();
  ++sharing.generation;  // and the old session's grants
  sharing.busy = 0;
  ++reading.generation;  // the slices and picks of the old volume, likewise
  reading.busy = 0;
  reading.crosshair.reset();
  reading.pick.reset();
  reading.pick_text.clear();
  for (SlicePane& pane : reading.panes) {
    pane.in_flight = pane.again = false;
    pane.image.reset();
  }
  Connect();
}

void App::RefreshVolumes() {
  connection->Request(
      [this](Client& client) {
        auto list = client.ListVolumes();
        Later([this, list = std::move(list)] { server_volumes = list; });
      },
      [this](const std::string& error) {
        if (!error.empty()) Later([this, error] { notice = error; });
      });
}

// ------------------------------------------------------------- the PACS

void App::ListPacs() {
  connection->Request(
      [this, generation = pacs.generation](Client& client) {
        std::vector<std::string> names = client.ListPacs();
        Later([this, generation, names = std::move(names)] {
          if (generation != pacs.generation) return;
          pacs.names = names;
          if (pacs.query.pacs().empty() && !names.empty()) pacs.query.set_pacs(names.front());
        });
      },
      [](const std::string&) {});  // a server without PACS, or older than them: no panel
}

void App::PacsCall(const std::string& action, const std::string& pacs_name,
                   std::function<std::function<void()>(Client&)> call) {
  ++pacs.busy;
  pacs.failed = false;
  connection->Request(
      [this, action, pacs_name, call = std::move(call), generation = pacs.generation](Client& client) {
        std::function<void()> then;
        try {
          then = call(client);
        } catch (const RpcError& e) {  // caught here rather than in Request's done, to keep the code
          then = [this, action, pacs_name, code = e.code(), text = std::string(e.what())] {
            PacsFailed(action, pacs_name, code, text);
          };
        } catch (const std::exception& e) {
          then = [this, action, pacs_name, text = std::string(e.what())] {
            PacsFailed(action, pacs_name, grpc::StatusCode::UNKNOWN, text);
          };
        }
        Later([this, generation, then = std::move(then)] {
          if (generation != pacs.generation) return;  // the connection closed meanwhile
          --pacs.busy;
          then();
        });
      },
      [](const std::string&) {});
}

void App::PacsFailed(const std::string& action, const std::string& pacs_name, grpc::StatusCode code,
                     const std::string& message) {
  pacs.status = message;
  pacs.failed = true;
  if (action == "openSeries") {
    pacs.opening = false;
    pacs.progress.reset();
  }
  // The code alone: a message may quote what was asked, a patient's name or ID.
  google::protobuf::Struct report;
  (*report.mutable_fields())["pacs"] = TextValue(pacs_name);
  (*report.mutable_fields())["error"] = TextValue(StatusCodeName(code));
  Report(action, report);
}

void App::SearchPacs(v1::SearchStudiesRequest query) {
  pacs.query = query;
  pacs.status = fmt::format("searching {}...", query.pacs());
  PacsCall("searchPacs", query.pacs(), [this, query](Client& client) -> std::function<void()> {
    return [this, query, studies = client.SearchStudies(query)] { ShowStudies(query, studies); };
  });
}

void App::ShowStudies(const v1::SearchStudiesRequest& query, const std::vector<v1::StudySummary>& studies) {
  pacs.source = query.pacs();
  pacs.studies = studies;
  pacs.study_uid.clear();
  pacs.series.clear();
  pacs.series_uid.clear();
  const std::size_t page = query.limit() > 0 ? query.limit() : 50;  // the server's default page
  pacs.status = studies.empty()       ? "no study matches"
                : studies.size() == 1 ? "1 study"
                                      : fmt::format("{} studies", studies.size());
  if (studies.size() >= page) pacs.status += " (a full page: narrow the search)";
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(query.pacs());
  auto& uids = *fields["studyUids"].mutable_list_value();
  for (const v1::StudySummary& s : studies) *uids.add_values() = TextValue(s.study_uid());
  Report("searchPacs", report);
}

void App::SelectStudy(const std::string& pacs_name, const std::string& study_uid) {
  pacs.source = pacs_name;
  pacs.study_uid = study_uid;
  pacs.series.clear();
  pacs.series_uid.clear();
  pacs.status = "listing the study's series...";
  PacsCall("selectStudy", pacs_name, [this, pacs_name, study_uid](Client& client) -> std::function<void()> {
    std::vector<v1::SeriesSummary> series = client.SearchSeries(pacs_name, study_uid);
    std::sort(series.begin(), series.end(),
              [](const auto& a, const auto& b) { return a.series_number() < b.series_number(); });
    return [this, pacs_name, study_uid, series = std::move(series)] { ShowSeries(pacs_name, study_uid, series); };
  });
}

void App::ShowSeries(const std::string& pacs_name, const std::string& study_uid,
                     const std::vector<v1::SeriesSummary>& series) {
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(pacs_name);
  fields["studyUid"] = TextValue(study_uid);
  auto& list = *fields["series"].mutable_list_value();
  for (const v1::SeriesSummary& s : series) *list.add_values() = SeriesValue(s);
  Report("selectStudy", report);
  if (pacs.study_uid != study_uid) return;  // another study was selected meanwhile
  pacs.series = series;
  pacs.series_uid = LargestSeries(series);  // Open takes it unless another is chosen
  pacs.status = series.size() == 1 ? "1 series" : fmt::format("{} series", series.size());
}

void App::OpenSeries(const v1::LoadSeriesRequest& request) {
  if (pacs.opening) {
    pacs.status = "a series is opening already: wait for it";
    return;
  }
  pacs.opening = true;
  pacs.progress.reset();
  pacs.status = "opening the series...";
  // The server fetches and reads the series; its progress comes back meanwhile.
  PacsCall("openSeries", request.pacs(), [this, request, generation = pacs.generation](Client& client) {
    auto on_progress = [this, generation](const v1::LoadSeriesProgress& p) {
      Later([this, generation, p] {
        if (generation == pacs.generation && pacs.opening) pacs.progress = p;
      });
    };
    return std::function<void()>(
        [this, request, opened = client.LoadSeries(request, on_progress)] { Opened(request, opened); });
  });
}

void App::Opened(const v1::LoadSeriesRequest& request, const v1::VolumeInfo& opened) {
  pacs.opening = false;
  pacs.progress.reset();
  pacs.status =
      fmt::format("opened {} ({} x {} x {})", opened.id(), opened.dims().x(), opened.dims().y(), opened.dims().z());
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(request.pacs());
  fields["studyUid"] = TextValue(request.study_uid());
  fields["seriesUid"] = TextValue(request.series_uid());
  fields["volumeId"] = TextValue(opened.id());
  fields["source"] = TextValue(opened.source());
  Report("openSeries", report);
  SwitchVolume(opened.id());  // as a click on one of the server's volumes does
}

void App::Report(const std::string& action, const google::protobuf::Struct& fields) const {
  if (!script_) return;  // a person's clicks print nothing
  std::string json;
  google::protobuf::util::MessageToJsonString(fields, &json);
  std::printf("cinevol-viewer: %s %s\n", action.c_str(), json.c_str());
  std::fflush(stdout);
}

void App::Snapshot(const std::string& path, int spp) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext != ".png" && ext != ".exr") {
    notice = fmt::format("snapshot {}: use .png or .exr", path);
    return;
  }
  v1::SnapshotRequest request;
  request.set_session_id(session_id);
  request.set_spp(spp);
  request.set_format(ext == ".exr" ? v1::EXR : v1::PNG);
  notice = fmt::format("rendering {} at {} spp...", path, spp);
  // No deadline: a still on a CPU server takes minutes. The line under the
  // panels follows its progress; closing the window cancels it.
  connection->Request(
      [this, request, path, stopping = &connection->stopping()](Client& client) {
        SnapshotOptions wait;
        wait.cancel = stopping;
        wait.on_progress = [this, path](const v1::SnapshotProgress& p) {
          Later([this, path, text = DescribeProgress(p)] { notice = fmt::format("rendering {}: {}", path, text); });
        };
        const v1::SnapshotResponse still = client.Snapshot(request, wait);
        WriteFile(path, std::vector<std::uint8_t>(still.image().begin(), still.image().end()));
        Later([this, path, still] {
          notice = fmt::format("wrote {} ({}x{}, {} spp, {:.1f} s)", path, still.width(), still.height(), still.spp(),
                               still.render_us() / 1e6);
        });
      },
      [this, path](const std::string& error) {
        if (!error.empty()) Later([this, path, error] { notice = fmt::format("snapshot {}: {}", path, error); });
      });
}

void App::SaveScene(const std::string& path) {
  v1::Scene scene;
  *scene.mutable_transfer_function() = transfer;
  *scene.mutable_camera() = ToProto(camera);
  scene.mutable_lights()->CopyFrom(lights.lights());
  *scene.mutable_render() = render;
  *scene.mutable_clipping() = clipping;
  if (labels.styles_size() > 0 || labels.has_show_unlisted() || labels.remove_table()) *scene.mutable_labels() = labels;
  for (const v1::Measurement& m : reading.measurements) *scene.add_measurements() = m;
  scene.mutable_render()->set_width(viewport_w_);
  scene.mutable_render()->set_height(viewport_h_);
  if (volume) {
    *scene.mutable_volume() = ParseVolumeSpec(volume->source());  // a phantom stays a phantom
    ToPatientFrame(scene, VolumePlacement::Of(*volume));          // one frame for the whole file, as its clipping
  }
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = true;
  std::string json;
  google::protobuf::util::MessageToJsonString(scene, &json, print);
  std::ofstream out(path);
  out << json;
  notice = out ? fmt::format("saved the scene to {}", path) : fmt::format("cannot write {}", path);
}

void App::OpenScene(const std::string& path) {
  try {
    v1::Scene scene = LoadSceneFile(path);
    if (volume) ToVolumeFrame(scene, VolumePlacement::Of(*volume));  // the viewer's camera and lights
    camera = FromProto(scene.camera(), camera);
    SendCamera();
    transfer = scene.transfer_function();
    if (transfer.points().empty() && volume) {
      transfer = MakePreset(transfer.preset().empty() ? volume->default_preset() : transfer.preset(),
                            AutoWindow(ToHistogram(volume->histogram())));
    }
    SendTransferFunction();
    // A file without lights keeps the lights on screen (sending none would
    // leave the volume black).
    if (scene.lights_size() > 0) {
      lights.mutable_lights()->CopyFrom(scene.lights());
      SendLights();
    }
    render.set_spp(scene.render().spp());
    render.set_max_bounces(scene.render().max_bounces());
    render.set_reconstruction(scene.render().reconstruction());
    SendRender();
    clipping = scene.clipping();
    SendClipping();
    labels = scene.labels();
    SendLabels();
    reading.measurements.assign(scene.measurements().begin(), scene.measurements().end());
    const bool styles = scene.labels().styles_size() > 0 || scene.labels().has_show_unlisted();
    notice = styles && !(volume && volume->has_labels())
                 ? fmt::format("opened {}; its label styles wait for a segmentation of this volume", path)
                 : fmt::format("opened {}", path);
    if (scene.lights_size() == 0) notice += " (it has no lights: the lights stay as they were)";
  } catch (const std::exception& e) {
    notice = e.what();
  }
}

// ------------------------------------------------------------ the frame

bool App::TakeFrame() {
  const Clock::time_point now = Clock::now();
  while (!stats.displayed.empty() && now - stats.displayed.front() > std::chrono::seconds(1))
    stats.displayed.pop_front();
  while (!stats.bytes.empty() && now - stats.bytes.front().first > std::chrono::seconds(1)) stats.bytes.pop_front();
  std::optional<ViewFrame> frame = connection->TakeFrame();
  if (!frame) return false;
  UploadFrame(*frame);
  const v1::Frame& f = frame->info;
  if (stats.last_frame_id > 0 && f.frame_id() > stats.last_frame_id + 1)
    stats.dropped += f.frame_id() - stats.last_frame_id - 1;
  for (std::uint64_t seq = stats.last.last_event_seq() + 1; seq <= f.last_event_seq(); ++seq) {
    if (const auto sent = connection->SentAt(seq)) {
      stats.latency_ms.push_back(Ms(now - *sent));
      if (script_) stats.all_latency_ms.push_back(stats.latency_ms.back());
    }
  }
  while (stats.latency_ms.size() > 200) stats.latency_ms.pop_front();
  stats.last_frame_id = f.frame_id();
  stats.last = f;
  stats.displayed.push_back(now);
  stats.last_shown = now;
  stats.bytes.emplace_back(now, frame->image_bytes);
  stats.decode_ms = frame->decode_ms;
  if (script_) stats.all_decode_ms.push_back(frame->decode_ms);
  stats.all_bytes += frame->image_bytes;
  return true;
}

std::string App::RendererName() const {
  SDL_RendererInfo info;
  return SDL_GetRendererInfo(renderer_, &info) == 0 ? info.name : "?";
}

void App::PrintSummary() const {
  const ViewerStats& s = stats;
  const double seconds = script_start_ ? std::chrono::duration<double>(Clock::now() - *script_start_).count() : 0;
  std::printf(
      "cinevol-viewer: %zu frames shown in %.1f s (%.1f fps), %.2f MB/s; event-to-frame latency p50/p95 %.1f/%.1f ms "
      "over %zu events; per frame shown: decode p50/p95 %.2f/%.2f ms (decoder thread), upload and draw p50/p95 "
      "%.2f/%.2f ms (UI thread, SDL renderer %s, video driver %s)\n",
      s.all_ui_ms.size(), seconds, seconds > 0 ? double(s.all_ui_ms.size()) / seconds : 0.0,
      seconds > 0 ? double(s.all_bytes) / seconds / 1e6 : 0.0, cli::Percentile(s.all_latency_ms, 0.5),
      cli::Percentile(s.all_latency_ms, 0.95), s.all_latency_ms.size(), cli::Percentile(s.all_decode_ms, 0.5),
      cli::Percentile(s.all_decode_ms, 0.95), cli::Percentile(s.all_ui_ms, 0.5), cli::Percentile(s.all_ui_ms, 0.95),
      RendererName().c_str(), SDL_GetCurrentVideoDriver());
  std::fflush(stdout);
}

void App::UploadFrame(const ViewFrame& frame) {
  const Clock::time_point start = Clock::now();
  const RgbImage& image = frame.image;
  if (!texture_ || texture_w_ != image.width || texture_h_ != image.height) {
    if (texture_) SDL_DestroyTexture(texture_);
    texture_ =
        SDL_CreateTexture(renderer_, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING, image.width, image.height);
    texture_w_ = image.width;
    texture_h_ = image.height;
  }
  if (texture_) SDL_UpdateTexture(texture_, nullptr, image.rgb.data(), image.width * 3);
  stats.upload_ms = Ms(Clock::now() - start);
}

void App::Layout() {
  int w = 0, h = 0, pw = 0, ph = 0;
  SDL_GetWindowSize(window_, &w, &h);
  SDL_GetRendererOutputSize(renderer_, &pw, &ph);
  pixel_scale_ = w > 0 ? float(pw) / float(w) : 1.0f;
  const float panel = std::min(kPanelWidth, float(w) * 0.5f);
  panel_area = {0, 0, panel, float(h)};
  frame_area = {panel, 0, float(w) - panel, float(h)};
  if (!reading.grid) return;
  // 2x2: the 3D view top left, axial top right, coronal and sagittal below.
  const float hw = frame_area.w / 2, hh = frame_area.h / 2;
  frame_area = {panel, 0, hw, hh};
  reading.panes[0].area = {panel + hw, 0, hw, hh};
  reading.panes[1].area = {panel, hh, hw, hh};
  reading.panes[2].area = {panel + hw, hh, hw, hh};
}

void App::DrawFrame() {
  if (!texture_) return;
  // Fit the frame into its area, keeping its aspect ratio (it matches once
  // a resize has settled).
  const float aw = frame_area.w * pixel_scale_, ah = frame_area.h * pixel_scale_;
  const float s = std::min(aw / float(texture_w_), ah / float(texture_h_));
  SDL_Rect dst;
  dst.w = int(std::lround(texture_w_ * s));
  dst.h = int(std::lround(texture_h_ * s));
  dst.x = int(std::lround(frame_area.x * pixel_scale_ + (aw - dst.w) / 2));
  dst.y = int(std::lround(frame_area.y * pixel_scale_ + (ah - dst.h) / 2));
  SDL_RenderCopy(renderer_, texture_, nullptr, &dst);
}

int App::Pixels(float logical) const { return std::max(16, int(std::lround(logical * pixel_scale_))); }

void App::ResizeViewportWhenSettled() {
  if (Watching()) return;  // the owner's window sets the session's size; its frames are fitted here
  const int w = Pixels(frame_area.w), h = Pixels(frame_area.h);
  if (w == viewport_w_ && h == viewport_h_) return;
  if (w != pending_w_ || h != pending_h_) {
    pending_w_ = w;
    pending_h_ = h;
    pending_since_ = Clock::now();
    return;
  }
  if (Clock::now() - pending_since_ < kResizeSettle || session_id.empty()) return;
  viewport_w_ = w;
  viewport_h_ = h;
  v1::SessionEvent e;
  e.mutable_resize()->set_width(w);
  e.mutable_resize()->set_height(h);
  Post(std::move(e));
}

bool App::ResizePending() const {
  return !Watching() && (Pixels(frame_area.w) != viewport_w_ || Pixels(frame_area.h) != viewport_h_);
}

// ------------------------------------------------------- mouse and keys

void App::PumpSdlEvents() {
  const ImGuiIO& io = ImGui::GetIO();
  SDL_Event e;
  while (SDL_PollEvent(&e)) {
    ImGui_ImplSDL2_ProcessEvent(&e);
    switch (e.type) {
      case SDL_QUIT:
        quit_ = true;
        break;
      case SDL_MOUSEBUTTONDOWN: {
        const float x = float(e.button.x), y = float(e.button.y);
        const int pane = SliceAt(x, y);
        if (!io.WantCaptureMouse && (frame_area.Contains(x, y) || pane >= 0)) {
          drag_button_ = e.button.button;
          drag_pane_ = pane;
          drag_x_ = press_x_ = x;
          drag_y_ = press_y_ = y;
          dragged_ = false;
        }
        break;
      }
      case SDL_MOUSEBUTTONUP:
        if (e.button.button == drag_button_) {
          if (!dragged_) Click(drag_button_, press_x_, press_y_);
          drag_button_ = 0;
        }
        break;
      case SDL_WINDOWEVENT:
        if (e.window.event == SDL_WINDOWEVENT_LEAVE) PointAt(std::nullopt);
        break;
      case SDL_MOUSEMOTION:
        if (const Rect shown = ShownFrame(); shown.Contains(float(e.motion.x), float(e.motion.y))) {
          PointAt(PointerShare::At{(float(e.motion.x) - shown.x) / shown.w, (float(e.motion.y) - shown.y) / shown.h});
        } else {
          PointAt(std::nullopt);
        }
        if (drag_button_) {
          const float dx = float(e.motion.x) - drag_x_, dy = float(e.motion.y) - drag_y_;
          dragged_ = dragged_ || std::hypot(float(e.motion.x) - press_x_, float(e.motion.y) - press_y_) > kClickSlop;
          if (drag_pane_ < 0) {
            Drag(drag_button_, dx, dy, SDL_GetModState());
          } else if (drag_button_ == SDL_BUTTON_LEFT && dragged_) {
            SliceWindowLevel(dx, dy);
          }
          drag_x_ = float(e.motion.x);
          drag_y_ = float(e.motion.y);
        }
        break;
      case SDL_MOUSEWHEEL: {
        if (io.WantCaptureMouse) break;
        int mx = 0, my = 0;
        SDL_GetMouseState(&mx, &my);
        if (const int pane = SliceAt(float(mx), float(my)); pane >= 0) {
          StepSlice(pane, float(e.wheel.y));
        } else {
          Wheel(float(e.wheel.y));
        }
        break;
      }
      case SDL_KEYDOWN:
        if (!io.WantCaptureKeyboard) Key(e.key.keysym.sym);
        break;
      default:
        break;
    }
  }
}

void App::Click(int button, float x, float y) {
  if (button != SDL_BUTTON_LEFT) return;
  if (const int pane = SliceAt(x, y); pane >= 0) {
    ClickSlice(pane, x, y);
  } else {
    PickAt(x, y);
  }
}

void App::Drag(int button, float dx, float dy, SDL_Keymod mods) {
  if (!Drives()) return;                                  // a viewer watches
  if (button == SDL_BUTTON_LEFT && (mods & KMOD_CTRL)) {  // the key light
    for (v1::Light& l : *lights.mutable_lights()) {
      if (!l.has_area()) continue;
      OrbitLight(*l.mutable_area(), camera, dx * kDegreesPerPixel, dy * kDegreesPerPixel);
      SendLights();
      break;
    }
  } else if (button == SDL_BUTTON_LEFT && (mods & KMOD_ALT)) {  // window (horizontal) and level (vertical)
    const float range = volume ? volume->max_value() - volume->min_value() : 1.0f;
    ApplyWindowLevel(transfer, -dy * range / 500.0f, std::exp(dx * 0.005f));
    SendTransferFunction();
  } else if (button == SDL_BUTTON_MIDDLE || (button == SDL_BUTTON_LEFT && (mods & KMOD_SHIFT))) {
    Pan(camera, dx, dy, int(frame_area.h));
    SendCamera();
  } else if (button == SDL_BUTTON_RIGHT) {
    Zoom(camera, std::exp(dy * 0.01f));
    SendCamera();
  } else if (button == SDL_BUTTON_LEFT) {
    Orbit(camera, dx * kDegreesPerPixel, dy * kDegreesPerPixel);
    SendCamera();
  }
}

void App::Wheel(float steps) {
  if (!Drives()) return;
  Zoom(camera, std::pow(0.9f, steps));
  SendCamera();
}

bool App::Key(SDL_Keycode key) {
  const SDL_Keymod mods = SDL_GetModState();
  if (key == SDLK_q && (mods & KMOD_CTRL)) {
    quit_ = true;
    return true;
  }
  if (key == SDLK_F2) {
    panels.stats = !panels.stats;
    return true;
  }
  if (key == SDLK_F3) {
    ToggleGrid();
    return true;
  }
  if (key == SDLK_F4) {
    reading.identity = !reading.identity;
    return true;
  }
  if (!Drives()) return false;
  if (key == SDLK_HOME || key == SDLK_SPACE) {
    camera = home;
    SendCamera();
    return true;
  }
  if ((mods & (KMOD_CTRL | KMOD_ALT)) || !volume) return false;  // named views follow the volume's axes
  static const std::pair<SDL_Keycode, v1::NamedView> kViews[] = {{SDLK_a, v1::ANTERIOR}, {SDLK_p, v1::POSTERIOR},
                                                                 {SDLK_l, v1::LEFT},     {SDLK_r, v1::RIGHT},
                                                                 {SDLK_s, v1::SUPERIOR}, {SDLK_i, v1::INFERIOR}};
  for (const auto& [k, view] : kViews) {
    if (k != key) continue;
    camera = NamedView(camera, view, volume->direction());
    SendCamera();
    return true;
  }
  return false;
}

// ------------------------------------------------------------ scripts

void App::RunScript() {
  if (!script_) return;
  if (Clock::now() - started_ > std::chrono::duration<double>(options.max_seconds)) {
    notice = fmt::format("the script did not finish within {} s (--max-seconds)", options.max_seconds);
    std::fprintf(stderr, "cinevol-viewer: %s\n", notice.c_str());
    exit_code_ = 1;
    finish_now_ = true;
    return;
  }
  if (!script_start_) {
    // It starts with the first frame, or once the server has failed for a
    // second (its UI actions still run: a screenshot shows the message).
    const bool broken = Broken(connection->status().state) && Clock::now() - started_ > std::chrono::seconds(1);
    if (!broken && (stats.last_frame_id == 0 || (!volume && !Watching()))) return;
    steps_ = cli::ExpandOrbits(script_->steps, volume.value_or(v1::VolumeInfo{}));
    script_start_ = Clock::now();
  }
  if (settling_) {  // the timeline stands still until the view has caught up
    const Clock::time_point now = Clock::now();
    if (!EventsAnswered() && !Broken(connection->status().state)) {
      *script_start_ += now - last_script_tick_;
      last_script_tick_ = now;
      return;
    }
    settling_ = false;
  }
  last_script_tick_ = Clock::now();
  const double t = std::chrono::duration<double>(last_script_tick_ - *script_start_).count();
  // A screenshot shows the window as the lines before it left it, so it ends
  // this turn's lines: it is read once this turn is drawn, and a slow turn
  // (a loaded machine) can leave later lines due already, such as a resize.
  while (!settling_ && screenshots_.empty() && next_step_ < steps_.size() && steps_[next_step_].at <= t) {
    const cli::ScriptStep& step = steps_[next_step_++];
    if (!step.ui.empty()) {
      RunUiAction(step.ui, step.line);
      continue;
    }
    const v1::SessionEvent& e = step.event;
    if (!Drives()) continue;  // no session, or a viewer's: events have nowhere to go
    if (e.has_camera()) {     // kept here, so that the mouse goes on from it
      camera = e.camera().view() != v1::NAMED_VIEW_UNSPECIFIED && volume
                   ? NamedView(camera, e.camera().view(), volume->direction())
                   : FromProto(e.camera(), camera);
      SendCamera();
      continue;
    }
    if (e.has_transfer_function()) {
      transfer = e.transfer_function();
      if (transfer.points().empty() && volume) {
        ChoosePreset(transfer.preset().empty() ? volume->default_preset() : transfer.preset());
        continue;
      }
    }
    // The panels show what the events set, as if they had set it: the
    // whole clipping and label styles replace the old, as on the server.
    if (e.has_lights()) lights = e.lights();
    if (e.has_render()) render.MergeFrom(e.render());
    if (e.has_stream()) stream.MergeFrom(e.stream());
    if (e.has_clipping()) clipping = e.clipping();
    if (e.has_labels()) labels = e.labels();
    Post(e);
  }
}

bool App::EventsAnswered() const {
  // A resized window is an event not sent yet (it waits for the window to
  // hold still), and the frame on screen is still of the old size.
  if (camera_dirty_ || ResizePending() || stats.last_frame_id == 0 || pacs.busy > 0 || reading.busy > 0 ||
      sharing.busy > 0)
    return false;
  // idle() before last_sent(): once nothing waits to be sent, last_sent()
  // counts every event posted; read first, it could miss events sent meanwhile.
  if (!connection->idle()) return false;
  return stats.last.last_event_seq() >= connection->last_sent();
}

bool App::ScriptDone() {
  const LinkStatus status = connection->status();
  const bool broken = Broken(status.state);
  // A watch the server ended for good (a revoked or expired grant, the
  // session's end) cannot come back: nothing later in the script can run.
  const bool watch_over = Watching() && status.state == LinkState::kFailed && script_start_;
  if (finish_now_ || watch_over || (broken && script_start_ && next_step_ >= steps_.size())) {
    if (broken && exit_code_ == 0) {
      exit_code_ = 3;
      std::fprintf(stderr, "cinevol-viewer: %s\n", status.message.c_str());
    }
    return true;
  }
  if (!script_start_ || next_step_ < steps_.size() || settling_) return false;
  // Every event answered, then a moment of refinement (or the final frame).
  if (!EventsAnswered()) {
    settled_since_.reset();
    return false;
  }
  if (!settled_since_) settled_since_ = Clock::now();
  return stats.last.final() || Clock::now() - *settled_since_ > std::chrono::duration<double>(kSettleSeconds);
}

void App::WriteScreenshot(const std::string& path) {
  int w = 0, h = 0;
  SDL_GetRendererOutputSize(renderer_, &w, &h);
  ImageRgb8 image;
  image.width = w;
  image.height = h;
  image.bytes.resize(std::size_t(w) * h * 3);
  if (SDL_RenderReadPixels(renderer_, nullptr, SDL_PIXELFORMAT_RGB24, image.bytes.data(), w * 3) != 0) {
    std::fprintf(stderr, "cinevol-viewer: cannot read the window: %s\n", SDL_GetError());
    exit_code_ = 1;
    return;
  }
  WriteFile(path, EncodePng(image));
  // Where things are, for whoever checks the screenshot (in its pixels).
  auto rect = [this](const Rect& r) {
    return fmt::format("[{:.0f}, {:.0f}, {:.0f}, {:.0f}]", r.x * pixel_scale_, r.y * pixel_scale_, r.w * pixel_scale_,
                       r.h * pixel_scale_);
  };
  const LinkStatus status = connection->status();
  std::string escaped;
  for (char c : status.message) escaped += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
  std::ofstream(std::filesystem::path(path).replace_extension(".layout.json")) << fmt::format(
      "{{\"window\": [{}, {}], \"frame\": {}, \"panel\": {}, \"stats\": {}, \"frameId\": {}, "
      "\"frameSize\": [{}, {}], \"accumulatedSpp\": {}, \"state\": {}, \"message\": \"{}\"}}\n",
      w, h, rect(frame_area), rect(panel_area), panels.stats ? rect(stats_area) : "null", stats.last.frame_id(),
      stats.last.width(), stats.last.height(), stats.last.accumulated_spp(), int(status.state), escaped);
}

}  // namespace cinevol::viewer

namespace cinevol::viewer {

int RunViewer(ViewerOptions options) {
  App app(std::move(options));
  return app.Run();
}

}  // namespace cinevol::viewer

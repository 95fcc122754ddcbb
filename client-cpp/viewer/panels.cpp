// The side panel's frame and the Volume and Scene panels; the stats overlay
// and the banner that says what is wrong.
#include "viewer/panels.h"

#include <fmt/format.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>

namespace cinevol::viewer {

void Hint(const char* text) {
  ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
  ImGui::TextWrapped("%s", text);
  ImGui::PopStyleColor();
}

namespace {

// The server's volumes, listed on request.
void ListVolumes(Rooms& r) {
  r.link.connection().Request(
      [&r](Client& client) {
        auto list = client.ListVolumes();
        r.context.ui.Later([&r, list = std::move(list)] { r.volumes.listed = list; });
      },
      [&r](const std::string& error) {
        if (!error.empty()) r.context.ui.Later([&r, error] { r.context.notice = error; });
      });
}

// A path field with a button that loads or uploads it on the requester,
// then switches the view to the new volume.
void VolumeField(Rooms& r, const char* verb, std::string& path,
                 std::function<v1::VolumeInfo(Client&, const std::string&)> open) {
  ImGui::PushID(verb);
  ImGui::InputText("##path", &path);
  ImGui::PopID();
  ImGui::SameLine();
  if (!ImGui::Button(verb) || path.empty()) return;
  r.context.notice = fmt::format("{} {}...", verb, path);
  r.link.connection().Request(
      [&r, open, path = path](Client& client) {
        const std::string id = open(client, path).id();
        r.context.ui.Later([&r, id] { r.switch_volume(id); });
      },
      [&r, verb, path = path](const std::string& error) {
        if (!error.empty()) {
          r.context.ui.Later([&r, verb, path, error] { r.context.notice = fmt::format("{} {}: {}", verb, path, error); });
        }
      });
}

void VolumePanel(Rooms& r) {
  const std::optional<v1::VolumeInfo>& volume = r.link.volume();
  if (volume) {
    const v1::VolumeInfo& v = *volume;
    ImGui::Text("%s", v.id().c_str());
    ImGui::TextWrapped("%s", v.source().c_str());
    ImGui::Text("%u x %u x %u voxels, %.3g x %.3g x %.3g mm", v.dims().x(), v.dims().y(), v.dims().z(),
                v.spacing_mm().x(), v.spacing_mm().y(), v.spacing_mm().z());
    ImGui::Text("modality %s, values %.6g .. %.6g %s", v.modality().empty() ? "unknown" : v.modality().c_str(),
                v.min_value(), v.max_value(), v.value_unit().c_str());
    ImGui::TextWrapped("kind: %s (%s)", v1::VolumeKind_Name(v.kind()).c_str(), v.kind_reason().c_str());
    ImGui::Text("default preset: %s", v.default_preset().c_str());
  }
  ImGui::Separator();
  if (ImGui::Button("Server's volumes")) ListVolumes(r);
  for (const v1::VolumeInfo& v : r.volumes.listed) {
    const bool current = volume && v.id() == volume->id();
    if (ImGui::Selectable(v.id().c_str(), current) && !current) r.switch_volume(v.id());
  }
  VolumeField(r, "Load", r.volumes.load_path, [](Client& c, const std::string& path) { return c.LoadVolume(path); });
  Hint("a file or DICOM folder under the server's data roots");
  VolumeField(r, "Upload", r.volumes.upload_path,
              [](Client& c, const std::string& path) { return c.UploadVolume(path); });
  Hint("a local .nii, .nii.gz, .nrrd, .mha or .vtk file");
}

// The paths a movie takes, in the combo's order: each sets MovieRequest's path.
// The phases' loop comes last, so that a still volume is offered the others.
struct MoviePath {
  const char* name;
  void (*set)(v1::MovieRequest&);
};
constexpr MoviePath kMoviePaths[] = {
    {"orbit (a whole turn)", [](v1::MovieRequest& r) { r.set_orbit_degrees(360); }},
    {"sweep axial", [](v1::MovieRequest& r) { r.set_sweep(v1::AXIAL); }},
    {"sweep coronal", [](v1::MovieRequest& r) { r.set_sweep(v1::CORONAL); }},
    {"sweep sagittal", [](v1::MovieRequest& r) { r.set_sweep(v1::SAGITTAL); }},
    {"phases (the loop)", [](v1::MovieRequest& r) { r.set_phases(true); }},
};
constexpr int kPhasesPath = IM_ARRAYSIZE(kMoviePaths) - 1;

// The movie's path: the phases only for a time series (a choice left from one falls back to the orbit).
void MoviePathCombo(SceneFiles& f, bool time_series) {
  const int offered = time_series ? IM_ARRAYSIZE(kMoviePaths) : kPhasesPath;
  if (f.movie_path < 0 || f.movie_path >= offered) f.movie_path = 0;
  if (!ImGui::BeginCombo("path", kMoviePaths[f.movie_path].name)) return;
  for (int i = 0; i < offered; ++i) {
    if (ImGui::Selectable(kMoviePaths[i].name, i == f.movie_path)) f.movie_path = i;
  }
  ImGui::EndCombo();
}

void ScenePanel(SceneFiles& f, bool time_series) {
  ImGui::InputText("scene file", &f.scene_path);
  if (ImGui::Button("Open")) f.Open(f.scene_path);
  ImGui::SameLine();
  if (ImGui::Button("Save")) f.Save(f.scene_path);
  ImGui::Separator();
  ImGui::InputText("snapshot", &f.snapshot_path);
  ImGui::SliderInt("snapshot spp", &f.snapshot_spp, 1, 4096, "%d", ImGuiSliderFlags_Logarithmic);
  if (ImGui::Button("Take snapshot (.png or .exr)")) f.Snapshot(f.snapshot_path, f.snapshot_spp);
  ImGui::Separator();
  ImGui::InputText("movie", &f.movie_file);
  MoviePathCombo(f, time_series);
  ImGui::SliderFloat("seconds", &f.movie_seconds, 1, 60, "%.0f");
  ImGui::SliderInt("movie spp", &f.movie_spp, 1, 1024, "%d", ImGuiSliderFlags_Logarithmic);
  if (f.movie_path == kPhasesPath) Hint("from the phase shown, at the Time panel's rate, looping; the camera stays");
  if (ImGui::Button("Record movie (.mp4, 25 frames/s)")) {
    v1::MovieRequest request;
    kMoviePaths[f.movie_path].set(request);
    request.set_seconds(f.movie_seconds);
    request.set_spp(f.movie_spp);
    f.Movie(f.movie_file, request);
  }
}

bool Header(const char* label, bool& open) {
  ImGui::SetNextItemOpen(open, ImGuiCond_Always);
  open = ImGui::CollapsingHeader(label);
  return open;
}

// A panel whose controls send events: greyed out while a grant's holder only watches.
void DrivingPanel(const SessionLink& link, const char* label, bool& open, const std::function<void()>& panel) {
  if (!Header(label, open)) return;
  ImGui::BeginDisabled(link.Watching() && !link.Drives());
  panel();
  ImGui::EndDisabled();
}

// What the banner says, or nothing while frames keep up.
std::string BannerText(const SessionLink& link, const ViewerStats& stats, const LinkStatus& status) {
  if (status.state != LinkState::kStreaming) return status.message;
  if (stats.last_frame_id == 0) return "waiting for the first frame...";
  const double waiting = std::chrono::duration<double>(Clock::now() - stats.last_shown).count();
  if (stats.last.last_event_seq() < link.connection().last_sent() && waiting > 3) {
    return fmt::format("the server has not answered for {:.0f} s: it may be busy or the network slow", waiting);
  }
  return {};
}

}  // namespace

void DrawPanels(Rooms& r) {
  PanelsOpen& open = r.panels;
  const Rect area = r.screen.panel_area();
  const bool watching = r.link.Watching();
  ImGui::SetNextWindowPos({area.x, area.y});
  ImGui::SetNextWindowSize({area.w, area.h});
  ImGui::Begin("cinevol", nullptr, ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  // A grant's holder watches another's session: what it can do is there.
  SessionLink& link = r.link;
  if (watching) WatchingPanel(r.sharing, link);
  if (!watching && Header("Volume", open.volume)) VolumePanel(r);
  if (!watching && !r.pacs.names.empty() && Header("PACS", open.pacs)) PacsPanel(r.pacs);
  const bool time_series = IsTimeSeries(link.volume());
  if (time_series) DrivingPanel(link, "Time", open.time, [&] { TimePanel(link, r.stats.last); });
  if (Fuses(link.shown().scene())) DrivingPanel(link, "Second volume", open.fusion, [&] { FusionPanel(link); });
  DrivingPanel(link, "Transfer function", open.transfer_function, [&] { TransferPanel(link, r.editor); });
  DrivingPanel(link, "Lights", open.lights, [&] { LightsPanel(link.shown()); });
  DrivingPanel(link, "Render", open.render, [&] { RenderPanel(link.shown()); });
  if (!watching) {  // these need the session's volume or its owner
    if (Header("Clipping", open.clipping)) ClippingPanel(link);
    if (Header("Labels", open.labels)) LabelsPanel(link);
    if (Header("Reading", open.reading)) ReadingPanel(r.reading, link);
    if (Header("Scene and snapshot", open.scene)) ScenePanel(r.files, time_series);
    const bool listed = open.share;
    if (Header("Share", open.share)) {
      if (!listed) r.sharing.ListShares();  // opened: the grants as they are now
      SharePanel(r.sharing, link);
    }
  }
  ImGui::Separator();
  ImGui::Checkbox("stats overlay (F2)", &open.stats);
  if (!r.context.notice.empty()) ImGui::TextWrapped("%s", r.context.notice.c_str());
  Hint("drag: orbit; right drag or wheel: zoom; middle or Shift drag: pan;");
  Hint("click: pick; F3: slices beside the 3D view (wheel: step, drag: window/level, click: crosshair);");
  Hint("A P L R S I: named views; Home: reset; Ctrl+Q: quit");
  if (watching) Hint("watching: the presenter drives; your mouse over the view is your pointer, where the grant shares it");
  ImGui::End();
}

void DrawStatsOverlay(const ViewerStats& s, const Screen& screen, OverlayAreas& overlays, bool open) {
  overlays.stats = {};
  if (!open) return;
  const Rect frame = screen.frame_area(), banner = overlays.banner;
  const float top = banner.h > 0 ? banner.y + banner.h + 6 : frame.y + 10;
  ImGui::SetNextWindowPos({frame.x + 10, top});  // below the line of a shared session
  ImGui::SetNextWindowBgAlpha(0.6f);
  ImGui::Begin("stats", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoInputs |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing);
  const v1::FrameTimings& t = s.last.timings();
  ImGui::Text("%.0f fps   %u x %u   %u spp", s.Fps(), s.last.width(), s.last.height(), s.last.accumulated_spp());
  if (s.latency_ms.empty()) {
    ImGui::Text("latency: no event answered yet");
  } else {
    ImGui::Text("latency p50 %.0f ms  p95 %.0f ms", s.LatencyPercentile(0.5), s.LatencyPercentile(0.95));
  }
  ImGui::Text("server: render %.1f  denoise %.1f  encode %.1f ms", t.render_us() / 1e3, t.denoise_us() / 1e3,
              t.encode_us() / 1e3);
  ImGui::Text("viewer: decode %.1f  upload %.1f  draw %.1f ms", s.decode_ms, s.upload_ms, s.draw_ms);
  ImGui::Text("%.2f MB/s   %llu frames dropped", s.BytesPerSecond() / 1e6, (unsigned long long)s.dropped);
  const ImVec2 pos = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
  overlays.stats = {pos.x, pos.y, size.x, size.y};
  ImGui::End();
}

void DrawStatusBanner(const SessionLink& link, const ViewerStats& stats, const Screen& screen) {
  const LinkStatus status = link.status();
  const std::string text = BannerText(link, stats, status);
  if (text.empty()) return;
  const bool bad = status.state == LinkState::kFailed || status.state == LinkState::kReconnecting ||
                   (status.state == LinkState::kStreaming && stats.last_frame_id > 0);
  const Rect frame = screen.frame_area();
  ImGui::SetNextWindowPos({frame.x + frame.w * 0.5f, frame.y + frame.h * 0.5f}, ImGuiCond_Always, {0.5f, 0.5f});
  // Sized to the text now: an auto-fit would lag a changed message by frames (a screenshot may come first).
  const float width = std::min(520.0f, frame.w - 20);
  const ImVec2 padding = ImGui::GetStyle().WindowPadding;
  ImGui::SetNextWindowSize(
      {width, ImGui::CalcTextSize(text.c_str(), nullptr, false, width - 2 * padding.x).y + 2 * padding.y});
  ImGui::Begin("status", nullptr, ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoSavedSettings);
  if (bad) ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.55f, 0.45f, 1.0f));
  ImGui::TextWrapped("%s", text.c_str());
  if (bad) ImGui::PopStyleColor();
  ImGui::End();
}

}  // namespace cinevol::viewer

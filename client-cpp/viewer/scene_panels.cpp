// The panels that edit the session's scene and settings: time, the second
// volume, transfer function, lights, render, clipping and labels. Each starts from the shown session
// (the server's state with this viewer's unanswered edits) and hands its
// edit back to it.
#include <fmt/format.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "viewer/panels.h"
#include "viewer/scene_files.h"
#include "viewer/second_volume.h"

namespace cinevol::viewer {

bool IsTimeSeries(const std::optional<v1::VolumeInfo>& volume) { return volume && volume->phases() > 1; }

namespace {

// "Phase 3 of 20 (240 ms)": counted from 1, with the phase's time where the series has times.
std::string PhaseLabel(const v1::VolumeInfo& volume, int phase) {
  std::string label = fmt::format("Phase {} of {}", phase + 1, volume.phases());
  if (phase < volume.phase_seconds_size()) label += fmt::format(" ({:.0f} ms)", volume.phase_seconds(phase) * 1e3);
  return label;
}

}  // namespace

void TimePanel(SessionLink& link, const v1::Frame& last) {
  const std::optional<v1::VolumeInfo>& volume = link.volume();
  if (!IsTimeSeries(volume)) return;
  ShownSession& session = link.shown();
  v1::Time time = session.scene().time();
  const int last_phase = int(volume->phases()) - 1;
  // Playing is the server's: Scene.time.phase stays where it began, the frames say where it is.
  int phase = std::min(int(time.playing() ? last.phase() : time.phase()), last_phase);
  ImGui::Text("%s", PhaseLabel(*volume, phase).c_str());
  bool changed = false;
  if (ImGui::SliderInt("phase", &phase, 0, last_phase, "%d", ImGuiSliderFlags_AlwaysClamp)) {
    time.set_playing(false);  // a phase chosen holds the series there
    changed = true;
  }
  if (ImGui::Button(time.playing() ? "Pause" : "Play")) {
    time.set_playing(!time.playing());  // paused on the phase shown, played on from it
    changed = true;
  }
  float rate = time.phases_per_second();
  if (ImGui::SliderFloat("phases/s", &rate, 0, 120, rate > 0 ? "%.1f" : "0: the series' own times",
                         ImGuiSliderFlags_AlwaysClamp)) {
    time.set_phases_per_second(rate);
    changed = true;
  }
  if (!changed) return;
  time.set_phase(std::uint32_t(phase));
  session.SetTime(time);
}

bool Fuses(const v1::Scene& scene) { return !scene.fusion().volume_id().empty(); }

namespace {

// The overlay's colour map, by ColorMap's names (HOT when unset, as the server draws it).
bool ColorMapCombo(v1::FusionOverlay& overlay) {
  const v1::ColorMap shown = overlay.color_map() == v1::COLOR_MAP_UNSPECIFIED ? v1::HOT : overlay.color_map();
  if (!ImGui::BeginCombo("colour map", v1::ColorMap_Name(shown).c_str())) return false;
  bool changed = false;
  for (const v1::ColorMap map : {v1::HOT, v1::RAINBOW, v1::GRAY}) {
    if (ImGui::Selectable(v1::ColorMap_Name(map).c_str(), map == shown) && map != shown) {
      overlay.set_color_map(map);
      changed = true;
    }
  }
  ImGui::EndCombo();
  return changed;
}

// The overlay's own window and level over the values shown from `lo` to
// `hi`, or none: the second volume's whole range. Whether one changed.
bool OverlayWindow(v1::FusionOverlay& overlay, float lo, float hi) {
  bool own = overlay.has_window();
  bool changed = ImGui::Checkbox("own window", &own);
  if (changed && own) {  // starts from the whole range it showed
    overlay.set_window(std::max(hi - lo, 1e-3f));
    overlay.set_level(0.5f * (lo + hi));
  } else if (changed) {
    overlay.clear_window();
    overlay.clear_level();
  }
  if (!overlay.has_window()) return changed;
  const float range = std::max(hi - lo, 1e-3f);
  float window = overlay.window(), level = overlay.level();
  if (ImGui::SliderFloat("window##overlay", &window, 1e-3f * range, 2 * range, "%.4g", ImGuiSliderFlags_AlwaysClamp)) {
    overlay.set_window(window);
    changed = true;
  }
  if (ImGui::SliderFloat("level##overlay", &level, lo, hi, "%.4g")) {
    overlay.set_level(level);
    changed = true;
  }
  return changed;
}

}  // namespace

void FusionPanel(SessionLink& link) {
  ShownSession& session = link.shown();
  v1::Fusion fusion = session.scene().fusion();
  ImGui::Text("%s%s", fusion.volume_id().c_str(), fusion.suv() ? " (SUVbw)" : "");
  v1::FusionOverlay& overlay = *fusion.mutable_overlay();
  float opacity = overlay.has_opacity() ? overlay.opacity() : 0.5f;
  bool changed = ImGui::SliderFloat("opacity", &opacity, 0, 1, "%.2f", ImGuiSliderFlags_AlwaysClamp);
  if (changed) overlay.set_opacity(opacity);
  changed |= ColorMapCombo(overlay);
  // Its range and glow need its description: the session's own viewer has it, a grant's holder not.
  if (const std::optional<v1::VolumeInfo>& fused = link.fused_volume()) {
    const double unit = fusion.suv() ? fused->suv_factor() : 1.0;  // the overlay's window is in SUVbw with suv
    changed |= OverlayWindow(overlay, float(fused->min_value() * unit), float(fused->max_value() * unit));
    bool glow = Glows(fusion);
    if (ImGui::Checkbox("glow in 3D", &glow)) {
      SetGlow(fusion, glow, *fused);
      changed = true;
    }
  }
  Hint("the overlay shows in the slices (F3), the glow in the 3D view");
  if (changed) session.SetFusion(fusion);
}

void TransferPanel(SessionLink& link, TransferEditorState& editor) {
  ShownSession& session = link.shown();
  v1::TransferFunction tf = session.scene().transfer_function();
  const std::string asked = session.ResolvingPreset();
  const std::string current = !asked.empty() ? asked : tf.preset().empty() ? "(edited)" : tf.preset();
  if (ImGui::BeginCombo("preset", current.c_str())) {
    for (const std::string& name : link.presets()) {  // the server's; it fits the one chosen to the volume
      if (ImGui::Selectable(name.c_str(), name == current)) {
        session.ChoosePreset(name);
        editor = {};
      }
    }
    ImGui::EndCombo();
  }
  if (!asked.empty()) {
    Hint("the server fits the preset to this volume...");
  } else if (link.volume() &&
             TransferFunctionEditor("##tf", tf, link.volume()->histogram(), editor, 140.0f)) {
    session.SetTransferFunction(tf);
  }
  Hint("Alt + drag in the view: window (sideways), level (up/down)");
}

namespace {

// The first area light is the key light.
v1::AreaLight* KeyLight(google::protobuf::RepeatedPtrField<v1::Light>& lights) {
  for (v1::Light& l : lights) {
    if (l.has_area()) return l.mutable_area();
  }
  return nullptr;
}

}  // namespace

void LightsPanel(ShownSession& session) {
  google::protobuf::RepeatedPtrField<v1::Light> lights = session.scene().lights();
  bool changed = false;
  if (v1::AreaLight* key = KeyLight(lights)) {
    float intensity = key->intensity();
    if (ImGui::SliderFloat("key light", &intensity, 0, 200, "%.1f", ImGuiSliderFlags_Logarithmic)) {
      key->set_intensity(intensity);
      changed = true;
    }
    const LightDirection at = DirectionOf(*key, session.camera());
    float azimuth = float(at.azimuth_deg), elevation = float(at.elevation_deg);
    const bool turned = ImGui::SliderFloat("azimuth", &azimuth, -180, 180, "%.0f deg");
    if (ImGui::SliderFloat("elevation", &elevation, -89, 89, "%.0f deg") || turned) {
      SetDirection(*key, session.camera(), {azimuth, elevation});
      changed = true;
    }
    bool visible = key->visible();
    if (ImGui::Checkbox("show the lamp", &visible)) {
      key->set_visible(visible);
      changed = true;
    }
    Hint("Ctrl + drag in the view turns the key light");
  }
  for (v1::Light& l : lights) {
    if (!l.has_environment()) continue;
    float intensity = l.environment().intensity();
    if (ImGui::SliderFloat("environment", &intensity, 0, 20, "%.2f", ImGuiSliderFlags_Logarithmic)) {
      l.mutable_environment()->set_intensity(intensity);
      changed = true;
    }
  }
  if (changed) session.SetLights(lights);
}

namespace {

// Speed for accuracy, from docs/tradeoff.md: what each costs is measured there.
struct Quality {
  const char* name;
  int spp, bounces;
  v1::Denoiser denoiser;
};
constexpr Quality kQualities[] = {
    {"fast: 1 spp, 2 bounces, wRLS", 1, 2, v1::DENOISER_WRLS},
    {"interactive: 2 spp, 4 bounces, wRLS", 2, 4, v1::DENOISER_WRLS},
    {"quality: 4 spp, 8 bounces, wRLS", 4, 8, v1::DENOISER_WRLS},
};

// What a render edit sends: samples, bounces and reconstruction (the size goes by resize).
v1::RenderSettings Sampling(const v1::RenderSettings& render) {
  v1::RenderSettings out;
  out.set_spp(render.spp());
  out.set_max_bounces(render.max_bounces());
  out.set_reconstruction(render.reconstruction() == v1::TRICUBIC ? v1::TRICUBIC : v1::TRILINEAR);
  return out;
}

// The stream settings' sliders: whether one changed.
bool StreamControls(v1::StreamSettings& stream) {
  bool changed = false;
  static const char* kDenoisers[] = {"server default (wRLS)", "none", "accumulate", "kNN", "guided", "SVGF", "wRLS"};
  int denoiser = stream.denoiser();
  if (ImGui::Combo("denoiser", &denoiser, kDenoisers, IM_ARRAYSIZE(kDenoisers))) {
    stream.set_denoiser(v1::Denoiser(denoiser));
    changed = true;
  }
  int quality = stream.has_jpeg_quality() ? int(stream.jpeg_quality()) : 80;
  if (ImGui::SliderInt("JPEG quality", &quality, 10, 100)) {
    stream.set_jpeg_quality(quality);
    changed = true;
  }
  int target = stream.has_target_spp() ? int(stream.target_spp()) : 256;
  if (ImGui::SliderInt("refine to spp", &target, 1, 4096, "%d", ImGuiSliderFlags_Logarithmic)) {
    stream.set_target_spp(target);
    changed = true;
  }
  float error = stream.has_error_target() ? stream.error_target() * 100.0f : 2.0f;
  if (ImGui::SliderFloat("refine to error %", &error, 0.0f, 5.0f, error > 0 ? "%.2f" : "off (to the spp cap)")) {
    stream.set_error_target(error / 100.0f);
    changed = true;
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("A still view refines until its estimated relative error is this low (or the spp cap)");
  }
  bool lossless = stream.final_format() == v1::FINAL_FORMAT_PNG;
  if (ImGui::Checkbox("lossless final frame (PNG)", &lossless)) {
    stream.set_final_format(lossless ? v1::FINAL_FORMAT_PNG : v1::FINAL_FORMAT_JPEG);
    changed = true;
  }
  float budget = stream.interactive_frame_ms();
  if (ImGui::SliderFloat("moving frame budget ms", &budget, 0.0f, 100.0f, budget > 0 ? "%.0f" : "off (full size)")) {
    stream.set_interactive_frame_ms(budget);
    changed = true;
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("While the view moves, render at 0.75 or 0.5 size when a full frame would take longer");
  }
  return changed;
}

}  // namespace

void RenderPanel(ShownSession& session) {
  v1::RenderSettings render = Sampling(session.scene().render());
  v1::StreamSettings stream = session.state().stream();
  for (const Quality& q : kQualities) {
    if (ImGui::Button(q.name)) {
      render.set_spp(q.spp);
      render.set_max_bounces(q.bounces);
      session.SetRender(render);
      stream.set_denoiser(q.denoiser);
      session.SetStream(stream);
    }
  }
  int spp = int(render.spp()), bounces = int(render.max_bounces());
  bool changed = false;
  if (ImGui::SliderInt("spp per frame", &spp, 1, 16)) render.set_spp(spp), changed = true;
  if (ImGui::SliderInt("bounces", &bounces, 0, 16)) render.set_max_bounces(bounces), changed = true;
  int cubic = render.reconstruction() == v1::TRICUBIC ? 1 : 0;
  static const char* kReconstructions[] = {"trilinear", "tricubic (smooth, 2-3x slower)"};
  if (ImGui::Combo("reconstruction", &cubic, kReconstructions, IM_ARRAYSIZE(kReconstructions))) {
    render.set_reconstruction(cubic ? v1::TRICUBIC : v1::TRILINEAR);
    changed = true;
  }
  if (changed) session.SetRender(render);
  if (StreamControls(stream)) session.SetStream(stream);
}

namespace {

// The volume's extent along the patient's L, P and S axes (mm): the corners
// of its voxels' box (half a voxel beyond the corner centres).
void PatientBounds(const Placement& placement, double lo[3], double hi[3]) {
  const Vec3d last = placement.dims() - Vec3d{0.5, 0.5, 0.5};
  for (int a = 0; a < 3; ++a) lo[a] = INFINITY, hi[a] = -INFINITY;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3d p = placement.IndexToPatient(
        {(corner & 1) ? last.x : -0.5, (corner & 2) ? last.y : -0.5, (corner & 4) ? last.z : -0.5});
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
  }
}

// Clip planes: each a normal (a patient axis either way, or its own) and an
// offset along it through the volume's extent. Returns whether one changed.
bool ClipPlanes(v1::Clipping& clipping, const float lo[3], const float hi[3]) {
  bool changed = false;
  const float centre[3] = {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2])};
  const float reach = 0.5f * std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
  for (int i = 0; i < clipping.planes_size(); ++i) {
    ImGui::PushID(i);
    v1::ClipPlane* plane = clipping.mutable_planes(i);
    float n[3] = {plane->normal().x(), plane->normal().y(), plane->normal().z()};
    const float length = std::max(1e-6f, std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
    // The plane as an offset from the volume's centre along its unit normal.
    float offset = ((plane->point().x() - centre[0]) * n[0] + (plane->point().y() - centre[1]) * n[1] +
                    (plane->point().z() - centre[2]) * n[2]) /
                   length;
    bool moved = ImGui::DragFloat3("normal (L P S)", n, 0.01f, -1.0f, 1.0f, "%.2f");
    moved |= ImGui::SliderFloat("offset mm", &offset, -reach, reach, "%.0f");
    bool cap = plane->cap();
    if (ImGui::Checkbox("cap", &cap)) {
      plane->set_cap(cap);
      changed = true;
    }
    ImGui::SameLine();
    const bool remove = ImGui::Button("remove");
    if (moved && n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 1e-6f) {
      const float l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      plane->mutable_normal()->set_x(n[0] / l);
      plane->mutable_normal()->set_y(n[1] / l);
      plane->mutable_normal()->set_z(n[2] / l);
      plane->mutable_point()->set_x(centre[0] + offset * n[0] / l);
      plane->mutable_point()->set_y(centre[1] + offset * n[1] / l);
      plane->mutable_point()->set_z(centre[2] + offset * n[2] / l);
      changed = true;
    }
    ImGui::PopID();
    if (remove) {
      clipping.mutable_planes()->DeleteSubrange(i, 1);
      return true;
    }
  }
  if (clipping.planes_size() < 6 && ImGui::Button("add a clip plane")) {
    v1::ClipPlane* plane = clipping.add_planes();  // keeps the inferior half: a cut from above
    plane->mutable_point()->set_x(centre[0]);
    plane->mutable_point()->set_y(centre[1]);
    plane->mutable_point()->set_z(centre[2]);
    plane->mutable_normal()->set_z(-1);
    changed = true;
  }
  Hint("each plane keeps the side its normal points to");
  return changed;
}

// The crop box's ranges along the patient's axes: whether one changed.
bool CropRanges(v1::CropBox& box, const float lo[3], const float hi[3]) {
  const char* labels[3] = {"R..L mm", "A..P mm", "I..S mm"};
  bool changed = false;
  for (int a = 0; a < 3; ++a) {
    const float c = a == 0 ? box.center().x() : a == 1 ? box.center().y() : box.center().z();
    const float s = a == 0 ? box.size().x() : a == 1 ? box.size().y() : box.size().z();
    float from = c - 0.5f * s, to = c + 0.5f * s;
    if (ImGui::DragFloatRange2(labels[a], &from, &to, 0.5f, lo[a], hi[a], "%.0f", "%.0f",
                               ImGuiSliderFlags_AlwaysClamp)) {
      to = std::max(to, from + 1.0f);  // at least 1 mm
      const float mid = 0.5f * (from + to), size = to - from;
      if (a == 0) box.mutable_center()->set_x(mid), box.mutable_size()->set_x(size);
      if (a == 1) box.mutable_center()->set_y(mid), box.mutable_size()->set_y(size);
      if (a == 2) box.mutable_center()->set_z(mid), box.mutable_size()->set_z(size);
      changed = true;
    }
  }
  bool cap = box.cap();
  if (ImGui::Checkbox("cap the cut faces", &cap)) {
    box.set_cap(cap);
    changed = true;
  }
  Hint("What lies outside the box is not rendered; capped faces show the tissue they cut");
  return changed;
}

}  // namespace

// A crop box along the patient's axes, as ranges over the volume's extent, and clip planes.
void ClippingPanel(SessionLink& link) {
  const std::optional<Placement> placement = link.placement();
  if (!placement) return;
  double lo_mm[3], hi_mm[3];
  PatientBounds(*placement, lo_mm, hi_mm);
  const float lo[3] = {float(lo_mm[0]), float(lo_mm[1]), float(lo_mm[2])};
  const float hi[3] = {float(hi_mm[0]), float(hi_mm[1]), float(hi_mm[2])};
  v1::Clipping clipping = link.shown().scene().clipping();
  bool changed = false;
  bool crop = clipping.has_crop_box();
  if (ImGui::Checkbox("crop box", &crop)) {
    clipping.clear_crop_box();
    if (crop) {
      v1::CropBox* box = clipping.mutable_crop_box();
      box->mutable_center()->set_x(0.5f * (lo[0] + hi[0]));
      box->mutable_center()->set_y(0.5f * (lo[1] + hi[1]));
      box->mutable_center()->set_z(0.5f * (lo[2] + hi[2]));
      box->mutable_size()->set_x(hi[0] - lo[0]);
      box->mutable_size()->set_y(hi[1] - lo[1]);
      box->mutable_size()->set_z(hi[2] - lo[2]);
    }
    changed = true;
  }
  changed |= ClipPlanes(clipping, lo, hi);
  if (clipping.has_crop_box()) changed |= CropRanges(*clipping.mutable_crop_box(), lo, hi);
  if (changed) link.shown().SetClipping(clipping);
}

namespace {

// The style of label `value`, added (visible, no change) when it has none.
v1::LabelStyle* StyleOf(v1::Labels& labels, std::uint32_t value) {
  for (v1::LabelStyle& style : *labels.mutable_styles()) {
    if (style.value() == value) return &style;
  }
  v1::LabelStyle* style = labels.add_styles();
  style->set_value(value);
  return style;
}

// Table removal: one switch, on any volume the server found a table in. Whether it changed.
bool TableSwitch(const v1::VolumeInfo& volume, v1::Labels& labels) {
  if (volume.table().voxels() == 0) {
    Hint(fmt::format("no table to remove: {}", volume.table().note()).c_str());
    return false;
  }
  bool remove = labels.remove_table();
  const bool changed = ImGui::Checkbox("remove table", &remove);
  if (changed) labels.set_remove_table(remove);
  ImGui::SameLine();
  Hint(fmt::format("({} voxels)", volume.table().voxels()).c_str());
  return changed;
}

// One row per label of the segmentation: shown or hidden, its colour. Whether one changed.
bool LabelRows(const v1::VolumeInfo& volume, v1::Labels& labels, bool unlisted) {
  static std::string filter;
  ImGui::InputText("filter", &filter);
  bool changed = false;
  ImGui::BeginChild("labels", {0, 240}, true);
  for (const v1::LabelName& label : volume.labels().names()) {
    const std::string name = label.name().empty() ? fmt::format("label {}", label.value()) : label.name();
    if (!filter.empty() && name.find(filter) == std::string::npos) continue;
    ImGui::PushID(int(label.value()));
    const v1::LabelStyle* style = nullptr;
    for (const v1::LabelStyle& s : labels.styles()) {
      if (s.value() == label.value()) style = &s;
    }
    bool visible = style ? !style->has_visible() || style->visible() : unlisted;
    float colour[3] = {0.8f, 0.8f, 0.8f};
    if (style && style->has_color()) colour[0] = style->color().r(), colour[1] = style->color().g(), colour[2] = style->color().b();
    if (ImGui::Checkbox("##visible", &visible)) {
      StyleOf(labels, label.value())->set_visible(visible);
      changed = true;
    }
    ImGui::SameLine();
    if (ImGui::ColorEdit3("##colour", colour, ImGuiColorEditFlags_NoInputs)) {
      v1::Color* c = StyleOf(labels, label.value())->mutable_color();
      c->set_r(colour[0]);
      c->set_g(colour[1]);
      c->set_b(colour[2]);
      changed = true;
    }
    ImGui::SameLine();
    ImGui::Text("%u %s (%llu voxels)", label.value(), name.c_str(), static_cast<unsigned long long>(label.voxels()));
    ImGui::PopID();
  }
  ImGui::EndChild();
  return changed;
}

}  // namespace

// Each label of the volume's segmentation: shown or hidden, its colour; and the table switch.
void LabelsPanel(SessionLink& link) {
  const std::optional<v1::VolumeInfo>& volume = link.volume();
  if (!volume) return;
  v1::Labels labels = link.shown().scene().labels();
  bool changed = TableSwitch(*volume, labels);
  if (!volume->has_labels()) {
    Hint("this volume has no segmentation: `cinevol volumes labels ID SEG` loads one, for sessions started after");
  } else {
    bool unlisted = !labels.has_show_unlisted() || labels.show_unlisted();
    if (ImGui::Checkbox("show labels left as they are", &unlisted)) {
      labels.set_show_unlisted(unlisted);
      changed = true;
    }
    changed |= LabelRows(*volume, labels, unlisted);
    if (ImGui::Button("reset styles")) {
      const bool remove_table = labels.remove_table();  // a switch of its own, not a style
      labels.Clear();
      labels.set_remove_table(remove_table);
      changed = true;
    }
  }
  if (changed) SetLabelsFor(link.shown(), volume, labels);
}

}  // namespace cinevol::viewer

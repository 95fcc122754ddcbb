// The viewer's panels (volume, PACS, transfer function, lights, render, clipping,
// labels, reading, scene, share), its stats overlay and the banner that says what is wrong.
#include <fmt/format.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "scene/presets.h"
#include "viewer/viewer_app.h"

namespace cinevol::viewer {

void Hint(const char* text) {
  ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
  ImGui::TextWrapped("%s", text);
  ImGui::PopStyleColor();
}

namespace {

// Text fields grow with what is typed (imgui_stdlib).
bool InputPath(const char* label, std::string& text) { return ImGui::InputText(label, &text); }

// A path field with a button that loads or uploads it on the worker, then
// switches the view to the new volume.
void VolumeField(App& app, const char* verb, std::string& path,
                 std::function<v1::VolumeInfo(Client&, const std::string&)> open) {
  ImGui::PushID(verb);
  InputPath("##path", path);
  ImGui::PopID();
  ImGui::SameLine();
  if (!ImGui::Button(verb) || path.empty()) return;
  app.notice = fmt::format("{} {}...", verb, path);
  app.connection->Request(
      [&app, open, path = path](Client& client) {
        const std::string id = open(client, path).id();
        app.Later([&app, id] { app.SwitchVolume(id); });
      },
      [&app, verb, path = path](const std::string& error) {
        if (!error.empty())
          app.Later([&app, verb, path, error] { app.notice = fmt::format("{} {}: {}", verb, path, error); });
      });
}

void VolumePanel(App& app) {
  if (app.volume) {
    const v1::VolumeInfo& v = *app.volume;
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
  if (ImGui::Button("Server's volumes")) app.RefreshVolumes();
  for (const v1::VolumeInfo& v : app.server_volumes) {
    const bool current = app.volume && v.id() == app.volume->id();
    if (ImGui::Selectable(v.id().c_str(), current) && !current) app.SwitchVolume(v.id());
  }
  VolumeField(app, "Load", app.load_path, [](Client& c, const std::string& path) { return c.LoadVolume(path); });
  Hint("a file or DICOM folder under the server's data roots");
  VolumeField(app, "Upload", app.upload_path, [](Client& c, const std::string& path) { return c.UploadVolume(path); });
  Hint("a local .nii, .nii.gz, .nrrd, .mha or .vtk file");
}

// "DOE^JOHN^P" as "DOE, JOHN P": DICOM's person name (its alphabetic group) for people.
std::string PersonName(const std::string& dicom) {
  std::vector<std::string> parts;
  std::string part;
  for (const char c : dicom.substr(0, dicom.find('=')) + '^') {
    if (c != '^') {
      part += c;
    } else if (!part.empty()) {
      parts.push_back(std::exchange(part, {}));
    }
  }
  std::string name = parts.empty() ? "" : parts.front();
  for (std::size_t i = 1; i < parts.size(); ++i) name += (i == 1 ? ", " : " ") + parts[i];
  return name;
}

// "20240115" as "2024-01-15"; anything else as it is.
std::string DateText(const std::string& dicom) {
  if (dicom.size() != 8) return dicom;
  return fmt::format("{}-{}-{}", dicom.substr(0, 4), dicom.substr(4, 2), dicom.substr(6, 2));
}

void Cell(const std::string& text) {
  ImGui::TableNextColumn();
  ImGui::TextUnformatted(text.c_str());
}

// Column headers over a table that scrolls both ways: the panel is narrow. Columns fit
// what they hold (resizable ones would keep the width of the empty table).
bool BeginResults(const char* id, std::initializer_list<const char*> columns, float height) {
  constexpr ImGuiTableFlags kFlags = ImGuiTableFlags_Borders | ImGuiTableFlags_RowBg | ImGuiTableFlags_ScrollX |
                                     ImGuiTableFlags_ScrollY | ImGuiTableFlags_SizingFixedFit;
  if (!ImGui::BeginTable(id, int(columns.size()), kFlags, {0, height})) return false;
  ImGui::TableSetupScrollFreeze(1, 1);
  for (const char* column : columns) ImGui::TableSetupColumn(column);
  ImGui::TableHeadersRow();
  return true;
}

// The PACS picker and the search fields; Enter in a field searches too.
void PacsSearch(App& app) {
  v1::SearchStudiesRequest& query = app.pacs.query;
  if (ImGui::BeginCombo("PACS", query.pacs().c_str())) {
    for (const std::string& name : app.pacs.names) {
      if (ImGui::Selectable(name.c_str(), name == query.pacs())) query.set_pacs(name);
    }
    ImGui::EndCombo();
  }
  constexpr ImGuiInputTextFlags kEnter = ImGuiInputTextFlags_EnterReturnsTrue;
  bool search = ImGui::InputTextWithHint("patient ID", "* and ? match", query.mutable_patient_id(), kEnter);
  search |= ImGui::InputTextWithHint("patient name", "DOE^J*", query.mutable_patient_name(), kEnter);
  search |= ImGui::InputTextWithHint("modality", "CT, MR", query.mutable_modality(), kEnter);
  search |= ImGui::InputTextWithHint("date from", "YYYYMMDD", query.mutable_study_date_from(), kEnter);
  search |= ImGui::InputTextWithHint("date to", "YYYYMMDD", query.mutable_study_date_to(), kEnter);
  search |= ImGui::Button("Search");
  if (search) app.SearchPacs(query);
}

void StudiesTable(App& app) {
  if (!BeginResults("studies", {"patient", "ID", "date", "modalities", "description"}, 150)) return;
  for (const v1::StudySummary& study : app.pacs.studies) {
    ImGui::TableNextRow();
    ImGui::TableNextColumn();
    ImGui::PushID(study.study_uid().c_str());
    const bool selected = study.study_uid() == app.pacs.study_uid;
    if (ImGui::Selectable(PersonName(study.patient_name()).c_str(), selected, ImGuiSelectableFlags_SpanAllColumns) &&
        !selected) {
      app.SelectStudy(app.pacs.source, study.study_uid());
    }
    ImGui::PopID();
    std::string modalities;
    for (const std::string& m : study.modalities()) modalities += (modalities.empty() ? "" : "/") + m;
    Cell(study.patient_id());
    Cell(DateText(study.study_date()));
    Cell(modalities);
    Cell(study.description());
  }
  ImGui::EndTable();
}

v1::LoadSeriesRequest SelectedSeries(const App& app) {
  v1::LoadSeriesRequest request;
  request.set_pacs(app.pacs.source);
  request.set_study_uid(app.pacs.study_uid);
  request.set_series_uid(app.pacs.series_uid);
  return request;
}

// The selected study's series: a click selects one, a double click opens it.
void SeriesTable(App& app) {
  if (!BeginResults("series", {"modality", "number", "instances", "description"}, 110)) return;
  for (const v1::SeriesSummary& series : app.pacs.series) {
    ImGui::TableNextRow();
    ImGui::TableNextColumn();
    ImGui::PushID(series.series_uid().c_str());
    constexpr ImGuiSelectableFlags kFlags = ImGuiSelectableFlags_SpanAllColumns | ImGuiSelectableFlags_AllowDoubleClick;
    if (ImGui::Selectable(series.modality().c_str(), series.series_uid() == app.pacs.series_uid, kFlags)) {
      app.pacs.series_uid = series.series_uid();
      if (ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left) && !app.pacs.opening) app.OpenSeries(SelectedSeries(app));
    }
    ImGui::PopID();
    Cell(series.has_series_number() ? std::to_string(series.series_number()) : "");
    Cell(series.has_instance_count() ? std::to_string(series.instance_count()) : "");
    Cell(series.description());
  }
  ImGui::EndTable();
}

// Open, and how far the series has come: "retrieving 12/20", then "reading" (the server decodes it).
void OpenButton(App& app) {
  ImGui::BeginDisabled(app.pacs.series_uid.empty() || app.pacs.opening);
  if (ImGui::Button("Open")) app.OpenSeries(SelectedSeries(app));
  ImGui::EndDisabled();
  if (!app.pacs.progress) return;
  const v1::LoadSeriesProgress& p = *app.pacs.progress;
  const bool reading = p.stage() == "reading";
  const float done = p.instances_total() > 0 ? float(p.instances_done()) / float(p.instances_total()) : 0.0f;
  const std::string text = reading ? fmt::format("reading {} instances", p.instances_total())
                                   : fmt::format("{} {}/{}", p.stage(), p.instances_done(), p.instances_total());
  ImGui::SameLine();
  ImGui::ProgressBar(reading ? 1.0f : done, {-1, 0}, text.c_str());
}

// Shown where the server names a PACS: search, a study's series, open one.
void PacsPanel(App& app) {
  PacsSearch(app);
  StudiesTable(app);
  SeriesTable(app);
  OpenButton(app);
  if (app.pacs.status.empty()) return;
  if (app.pacs.failed) ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.55f, 0.45f, 1.0f));
  ImGui::TextWrapped("%s", app.pacs.status.c_str());
  if (app.pacs.failed) ImGui::PopStyleColor();
}

void TransferPanel(App& app) {
  const std::string current = app.transfer.preset().empty() ? "(edited)" : app.transfer.preset();
  if (ImGui::BeginCombo("preset", current.c_str())) {
    for (const std::string& name : PresetNames()) {
      if (ImGui::Selectable(name.c_str(), name == app.transfer.preset())) app.ChoosePreset(name);
    }
    ImGui::EndCombo();
  }
  if (app.volume && TransferFunctionEditor("##tf", app.transfer, app.volume->histogram(), app.editor, 140.0f)) {
    app.SendTransferFunction();
  }
  Hint("Alt + drag in the view: window (sideways), level (up/down)");
}

// The first area light is the key light.
v1::AreaLight* KeyLight(App& app) {
  for (v1::Light& l : *app.lights.mutable_lights()) {
    if (l.has_area()) return l.mutable_area();
  }
  return nullptr;
}

void LightsPanel(App& app) {
  if (v1::AreaLight* key = KeyLight(app)) {
    float intensity = key->intensity();
    if (ImGui::SliderFloat("key light", &intensity, 0, 200, "%.1f", ImGuiSliderFlags_Logarithmic)) {
      key->set_intensity(intensity);
      app.SendLights();
    }
    LightDirection direction = DirectionOf(*key, app.camera);
    const bool turned = ImGui::SliderFloat("azimuth", &direction.azimuth_deg, -180, 180, "%.0f deg");
    if (ImGui::SliderFloat("elevation", &direction.elevation_deg, -89, 89, "%.0f deg") || turned) {
      SetDirection(*key, app.camera, direction);
      app.SendLights();
    }
    bool visible = key->visible();
    if (ImGui::Checkbox("show the lamp", &visible)) {
      key->set_visible(visible);
      app.SendLights();
    }
    Hint("Ctrl + drag in the view turns the key light");
  }
  for (v1::Light& l : *app.lights.mutable_lights()) {
    if (!l.has_environment()) continue;
    float intensity = l.environment().intensity();
    if (ImGui::SliderFloat("environment", &intensity, 0, 20, "%.2f", ImGuiSliderFlags_Logarithmic)) {
      l.mutable_environment()->set_intensity(intensity);
      app.SendLights();
    }
  }
}

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

void RenderPanel(App& app) {
  for (const Quality& q : kQualities) {
    if (ImGui::Button(q.name)) {
      app.render.set_spp(q.spp);
      app.render.set_max_bounces(q.bounces);
      app.stream.set_denoiser(q.denoiser);
      app.SendRender();
      app.SendStream();
    }
  }
  int spp = int(app.render.spp()), bounces = int(app.render.max_bounces());
  if (ImGui::SliderInt("spp per frame", &spp, 1, 16)) {
    app.render.set_spp(spp);
    app.SendRender();
  }
  if (ImGui::SliderInt("bounces", &bounces, 0, 16)) {
    app.render.set_max_bounces(bounces);
    app.SendRender();
  }
  int cubic = app.render.reconstruction() == v1::TRICUBIC ? 1 : 0;
  static const char* kReconstructions[] = {"trilinear", "tricubic (smooth, 2-3x slower)"};
  if (ImGui::Combo("reconstruction", &cubic, kReconstructions, IM_ARRAYSIZE(kReconstructions))) {
    app.render.set_reconstruction(cubic ? v1::TRICUBIC : v1::TRILINEAR);
    app.SendRender();
  }
  static const char* kDenoisers[] = {"server default (wRLS)", "none", "accumulate", "kNN", "guided", "SVGF", "wRLS"};
  int denoiser = app.stream.denoiser();
  if (ImGui::Combo("denoiser", &denoiser, kDenoisers, IM_ARRAYSIZE(kDenoisers))) {
    app.stream.set_denoiser(v1::Denoiser(denoiser));
    app.SendStream();
  }
  int quality = app.stream.has_jpeg_quality() ? int(app.stream.jpeg_quality()) : 80;
  if (ImGui::SliderInt("JPEG quality", &quality, 10, 100)) {
    app.stream.set_jpeg_quality(quality);
    app.SendStream();
  }
  int target = app.stream.has_target_spp() ? int(app.stream.target_spp()) : 256;
  if (ImGui::SliderInt("refine to spp", &target, 1, 4096, "%d", ImGuiSliderFlags_Logarithmic)) {
    app.stream.set_target_spp(target);
    app.SendStream();
  }
  float error = app.stream.has_error_target() ? app.stream.error_target() * 100.0f : 2.0f;
  if (ImGui::SliderFloat("refine to error %", &error, 0.0f, 5.0f, error > 0 ? "%.2f" : "off (to the spp cap)")) {
    app.stream.set_error_target(error / 100.0f);
    app.SendStream();
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("A still view refines until its estimated relative error is this low (or the spp cap)");
  }
  bool lossless = app.stream.final_format() == v1::FINAL_FORMAT_PNG;
  if (ImGui::Checkbox("lossless final frame (PNG)", &lossless)) {
    app.stream.set_final_format(lossless ? v1::FINAL_FORMAT_PNG : v1::FINAL_FORMAT_JPEG);
    app.SendStream();
  }
  float budget = app.stream.interactive_frame_ms();
  if (ImGui::SliderFloat("moving frame budget ms", &budget, 0.0f, 100.0f, budget > 0 ? "%.0f" : "off (full size)")) {
    app.stream.set_interactive_frame_ms(budget);
    app.SendStream();
  }
  if (ImGui::IsItemHovered()) {
    ImGui::SetTooltip("While the view moves, render at 0.75 or 0.5 size when a full frame would take longer");
  }
}

// The volume's extent along the patient's L, P and S axes (mm): the corners
// of its voxel grid through its origin and direction cosines.
void PatientBounds(const v1::VolumeInfo& v, float lo[3], float hi[3]) {
  const float n[3] = {float(v.dims().x()), float(v.dims().y()), float(v.dims().z())};
  const float s[3] = {v.spacing_mm().x(), v.spacing_mm().y(), v.spacing_mm().z()};
  const float o[3] = {v.origin_mm().x(), v.origin_mm().y(), v.origin_mm().z()};
  for (int r = 0; r < 3; ++r) lo[r] = hi[r] = o[r];
  for (int corner = 0; corner < 8; ++corner) {
    for (int r = 0; r < 3; ++r) {
      float p = o[r];
      for (int c = 0; c < 3; ++c) {
        const double d = v.direction_size() == 9 ? v.direction(3 * r + c) : (r == c ? 1.0 : 0.0);
        p += float(d) * ((corner >> c & 1) ? n[c] - 0.5f : -0.5f) * s[c];
      }
      lo[r] = std::min(lo[r], p);
      hi[r] = std::max(hi[r], p);
    }
  }
}

// Clip planes: each a normal (a patient axis either way, or its own) and an
// offset along it through the volume's extent. Returns whether one changed.
bool ClipPlanes(App& app, const float lo[3], const float hi[3]) {
  bool changed = false;
  const float centre[3] = {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2])};
  const float reach = 0.5f * std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
  for (int i = 0; i < app.clipping.planes_size(); ++i) {
    ImGui::PushID(i);
    v1::ClipPlane* plane = app.clipping.mutable_planes(i);
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
      app.clipping.mutable_planes()->DeleteSubrange(i, 1);
      return true;
    }
  }
  if (app.clipping.planes_size() < 6 && ImGui::Button("add a clip plane")) {
    v1::ClipPlane* plane = app.clipping.add_planes();  // keeps the inferior half: a cut from above
    plane->mutable_point()->set_x(centre[0]);
    plane->mutable_point()->set_y(centre[1]);
    plane->mutable_point()->set_z(centre[2]);
    plane->mutable_normal()->set_z(-1);
    changed = true;
  }
  Hint("each plane keeps the side its normal points to");
  return changed;
}

// A crop box along the patient's axes, as ranges over the volume's extent,
// and clip planes.
void ClippingPanel(App& app) {
  if (!app.volume) return;
  float lo[3], hi[3];
  PatientBounds(*app.volume, lo, hi);
  bool crop = app.clipping.has_crop_box();
  if (ImGui::Checkbox("crop box", &crop)) {
    app.clipping.clear_crop_box();
    if (crop) {
      v1::CropBox* box = app.clipping.mutable_crop_box();
      box->mutable_center()->set_x(0.5f * (lo[0] + hi[0]));
      box->mutable_center()->set_y(0.5f * (lo[1] + hi[1]));
      box->mutable_center()->set_z(0.5f * (lo[2] + hi[2]));
      box->mutable_size()->set_x(hi[0] - lo[0]);
      box->mutable_size()->set_y(hi[1] - lo[1]);
      box->mutable_size()->set_z(hi[2] - lo[2]);
    }
    app.SendClipping();
  }
  if (ClipPlanes(app, lo, hi)) app.SendClipping();
  if (!app.clipping.has_crop_box()) return;
  v1::CropBox* box = app.clipping.mutable_crop_box();
  const char* labels[3] = {"R..L mm", "A..P mm", "I..S mm"};
  bool changed = false;
  for (int a = 0; a < 3; ++a) {
    const float c = a == 0 ? box->center().x() : a == 1 ? box->center().y() : box->center().z();
    const float s = a == 0 ? box->size().x() : a == 1 ? box->size().y() : box->size().z();
    float from = c - 0.5f * s, to = c + 0.5f * s;
    if (ImGui::DragFloatRange2(labels[a], &from, &to, 0.5f, lo[a], hi[a], "%.0f", "%.0f",
                               ImGuiSliderFlags_AlwaysClamp)) {
      to = std::max(to, from + 1.0f);  // at least 1 mm
      const float mid = 0.5f * (from + to), size = to - from;
      if (a == 0) box->mutable_center()->set_x(mid), box->mutable_size()->set_x(size);
      if (a == 1) box->mutable_center()->set_y(mid), box->mutable_size()->set_y(size);
      if (a == 2) box->mutable_center()->set_z(mid), box->mutable_size()->set_z(size);
      changed = true;
    }
  }
  bool cap = box->cap();
  if (ImGui::Checkbox("cap the cut faces", &cap)) {
    box->set_cap(cap);
    changed = true;
  }
  Hint("What lies outside the box is not rendered; capped faces show the tissue they cut");
  if (changed) app.SendClipping();
}

// The style of label `value`, added (visible, no change) when it has none.
v1::LabelStyle* StyleOf(v1::Labels& labels, std::uint32_t value) {
  for (v1::LabelStyle& style : *labels.mutable_styles()) {
    if (style.value() == value) return &style;
  }
  v1::LabelStyle* style = labels.add_styles();
  style->set_value(value);
  return style;
}

// Table removal: one switch, on any volume the server found a table in.
void TableSwitch(App& app) {
  if (!app.volume || app.volume->table().voxels() == 0) {
    if (app.volume) Hint(fmt::format("no table to remove: {}", app.volume->table().note()).c_str());
    return;
  }
  bool remove = app.labels.remove_table();
  if (ImGui::Checkbox("remove table", &remove)) {
    app.labels.set_remove_table(remove);
    app.SendLabels();
  }
  ImGui::SameLine();
  Hint(fmt::format("({} voxels)", app.volume->table().voxels()).c_str());
}

// Each label of the volume's segmentation: shown or hidden, its colour.
void LabelsPanel(App& app) {
  TableSwitch(app);
  if (!app.volume || !app.volume->has_labels()) {
    Hint("this volume has no segmentation: `cinevol volumes labels ID SEG` loads one, for sessions started after");
    return;
  }
  bool changed = false;
  bool unlisted = !app.labels.has_show_unlisted() || app.labels.show_unlisted();
  if (ImGui::Checkbox("show labels left as they are", &unlisted)) {
    app.labels.set_show_unlisted(unlisted);
    changed = true;
  }
  static std::string filter;
  ImGui::InputText("filter", &filter);
  ImGui::BeginChild("labels", {0, 240}, true);
  for (const v1::LabelName& label : app.volume->labels().names()) {
    const std::string name = label.name().empty() ? fmt::format("label {}", label.value()) : label.name();
    if (!filter.empty() && name.find(filter) == std::string::npos) continue;
    ImGui::PushID(int(label.value()));
    const v1::LabelStyle* style = nullptr;
    for (const v1::LabelStyle& s : app.labels.styles()) {
      if (s.value() == label.value()) style = &s;
    }
    bool visible = style ? !style->has_visible() || style->visible() : unlisted;
    if (ImGui::Checkbox("##visible", &visible)) {
      StyleOf(app.labels, label.value())->set_visible(visible);
      changed = true;
    }
    ImGui::SameLine();
    float colour[3] = {0.8f, 0.8f, 0.8f};
    if (style && style->has_color())
      colour[0] = style->color().r(), colour[1] = style->color().g(), colour[2] = style->color().b();
    if (ImGui::ColorEdit3("##colour", colour, ImGuiColorEditFlags_NoInputs)) {
      v1::Color* c = StyleOf(app.labels, label.value())->mutable_color();
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
  if (ImGui::Button("reset styles")) {
    const bool remove_table = app.labels.remove_table();  // a switch of its own, not a style
    app.labels.Clear();
    app.labels.set_remove_table(remove_table);
    changed = true;
  }
  if (changed) app.SendLabels();
}

void ScenePanel(App& app) {
  InputPath("scene file", app.scene_path);
  if (ImGui::Button("Open")) app.OpenScene(app.scene_path);
  ImGui::SameLine();
  if (ImGui::Button("Save")) app.SaveScene(app.scene_path);
  ImGui::Separator();
  InputPath("snapshot", app.snapshot_path);
  ImGui::SliderInt("snapshot spp", &app.snapshot_spp, 1, 4096, "%d", ImGuiSliderFlags_Logarithmic);
  if (ImGui::Button("Take snapshot (.png or .exr)")) app.Snapshot(app.snapshot_path, app.snapshot_spp);
}

bool Header(const char* label, bool& open) {
  ImGui::SetNextItemOpen(open, ImGuiCond_Always);
  open = ImGui::CollapsingHeader(label);
  return open;
}

// A panel whose controls send events: greyed out while a grant's holder only watches.
void DrivingPanel(App& app, const char* label, bool& open, void (*panel)(App&)) {
  if (!Header(label, open)) return;
  ImGui::BeginDisabled(app.Watching() && !app.Drives());
  panel(app);
  ImGui::EndDisabled();
}

}  // namespace

void DrawPanels(App& app) {
  ImGui::SetNextWindowPos({app.panel_area.x, app.panel_area.y});
  ImGui::SetNextWindowSize({app.panel_area.w, app.panel_area.h});
  ImGui::Begin("cinevol", nullptr, ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  // A grant's holder watches another's session: what it can do is there.
  if (app.Watching()) WatchingPanel(app);
  if (!app.Watching() && Header("Volume", app.panels.volume)) VolumePanel(app);
  if (!app.Watching() && !app.pacs.names.empty() && Header("PACS", app.panels.pacs)) PacsPanel(app);
  DrivingPanel(app, "Transfer function", app.panels.transfer_function, TransferPanel);
  DrivingPanel(app, "Lights", app.panels.lights, LightsPanel);
  DrivingPanel(app, "Render", app.panels.render, RenderPanel);
  if (!app.Watching()) {  // these need the session's volume or its owner
    if (Header("Clipping", app.panels.clipping)) ClippingPanel(app);
    if (Header("Labels", app.panels.labels)) LabelsPanel(app);
    if (Header("Reading", app.panels.reading)) ReadingPanel(app);
    if (Header("Scene and snapshot", app.panels.scene)) ScenePanel(app);
    const bool listed = app.panels.share;
    if (Header("Share", app.panels.share)) {
      if (!listed) app.ListShares();  // opened: the grants as they are now
      SharePanel(app);
    }
  }
  ImGui::Separator();
  ImGui::Checkbox("stats overlay (F2)", &app.panels.stats);
  if (!app.notice.empty()) ImGui::TextWrapped("%s", app.notice.c_str());
  Hint("drag: orbit; right drag or wheel: zoom; middle or Shift drag: pan;");
  Hint("click: pick; F3: slices beside the 3D view (wheel: step, drag: window/level, click: crosshair);");
  Hint("A P L R S I: named views; Home: reset; Ctrl+Q: quit");
  if (app.Watching())
    Hint("watching: the presenter drives; your mouse over the view is your pointer, where the grant shares it");
  ImGui::End();
}

void DrawStatsOverlay(App& app) {
  const ViewerStats& s = app.stats;
  const float top = app.banner_area.h > 0 ? app.banner_area.y + app.banner_area.h + 6 : app.frame_area.y + 10;
  ImGui::SetNextWindowPos({app.frame_area.x + 10, top});  // below the line of a shared session
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
  app.stats_area = {pos.x, pos.y, size.x, size.y};
  ImGui::End();
}

// What the banner says, or nothing while frames keep up.
std::string BannerText(const App& app, const LinkStatus& status) {
  if (status.state != LinkState::kStreaming) return status.message;
  if (app.stats.last_frame_id == 0) return "waiting for the first frame...";
  const double waiting = std::chrono::duration<double>(Clock::now() - app.stats.last_shown).count();
  if (app.stats.last.last_event_seq() < app.connection->last_sent() && waiting > 3) {
    return fmt::format("the server has not answered for {:.0f} s: it may be busy or the network slow", waiting);
  }
  return {};
}

void DrawStatusBanner(App& app, const LinkStatus& status) {
  const std::string text = BannerText(app, status);
  if (text.empty()) return;
  const bool bad = status.state == LinkState::kFailed || status.state == LinkState::kReconnecting ||
                   (status.state == LinkState::kStreaming && app.stats.last_frame_id > 0);
  ImGui::SetNextWindowPos({app.frame_area.x + app.frame_area.w * 0.5f, app.frame_area.y + app.frame_area.h * 0.5f},
                          ImGuiCond_Always, {0.5f, 0.5f});
  // Sized to the text now: an auto-fit would lag a changed message by frames (a screenshot may come first).
  const float width = std::min(520.0f, app.frame_area.w - 20);
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

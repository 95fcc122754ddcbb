// The PACS panel: the search fields, the studies found, a study's series and
// Open (images, a measurement report, a segmentation or a presentation state, by modality), with
// the series' progress while the server fetches it; Store measurements.
#include <fmt/format.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <initializer_list>

#include "viewer/panels.h"
#include "viewer/reading_view.h"

namespace cinevol::viewer {
namespace {

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
void SearchFields(PacsBrowser& pacs) {
  v1::SearchStudiesRequest& query = pacs.query;
  if (ImGui::BeginCombo("PACS", query.pacs().c_str())) {
    for (const std::string& name : pacs.names) {
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
  if (search) pacs.Search(query);
}

void StudiesTable(PacsBrowser& pacs) {
  if (!BeginResults("studies", {"patient", "ID", "date", "modalities", "description"}, 150)) return;
  for (const v1::StudySummary& study : pacs.studies) {
    ImGui::TableNextRow();
    ImGui::TableNextColumn();
    ImGui::PushID(study.study_uid().c_str());
    const bool selected = study.study_uid() == pacs.study_uid;
    if (ImGui::Selectable(PersonName(study.patient_name()).c_str(), selected, ImGuiSelectableFlags_SpanAllColumns) &&
        !selected) {
      pacs.SelectStudy(pacs.source, study.study_uid());
    }
    ImGui::PopID();
    std::string modalities;
    for (const std::string& m : study.modalities()) modalities += (modalities.empty() ? "" : "/") + m;
    Cell(study.patient_id());
    Cell(StudyDate(study.study_date()));
    Cell(modalities);
    Cell(study.description());
  }
  ImGui::EndTable();
}

// The selected study's series: a click selects one, a double click opens it.
void SeriesTable(PacsBrowser& pacs) {
  if (!BeginResults("series", {"modality", "number", "instances", "description"}, 110)) return;
  for (const v1::SeriesSummary& series : pacs.series) {
    ImGui::TableNextRow();
    ImGui::TableNextColumn();
    ImGui::PushID(series.series_uid().c_str());
    constexpr ImGuiSelectableFlags kFlags = ImGuiSelectableFlags_SpanAllColumns | ImGuiSelectableFlags_AllowDoubleClick;
    if (ImGui::Selectable(series.modality().c_str(), series.series_uid() == pacs.series_uid, kFlags)) {
      pacs.series_uid = series.series_uid();
      if (ImGui::IsMouseDoubleClicked(ImGuiMouseButton_Left) && !pacs.opening) pacs.OpenSeries(pacs.SelectedSeries());
    }
    ImGui::PopID();
    Cell(series.has_series_number() ? std::to_string(series.series_number()) : "");
    Cell(series.has_instance_count() ? std::to_string(series.instance_count()) : "");
    Cell(series.description());
  }
  ImGui::EndTable();
}

// Open, and how far the series has come: "retrieving 12/20", then "reading" (the server decodes it).
void OpenButton(PacsBrowser& pacs) {
  ImGui::BeginDisabled(pacs.series_uid.empty() || pacs.opening);
  if (ImGui::Button("Open")) pacs.OpenSeries(pacs.SelectedSeries());
  ImGui::EndDisabled();
  if (!pacs.progress) return;
  const v1::LoadSeriesProgress& p = *pacs.progress;
  const bool reading = p.stage() == "reading";
  const float done = p.instances_total() > 0 ? float(p.instances_done()) / float(p.instances_total()) : 0.0f;
  const std::string text = reading ? fmt::format("reading {} instances", p.instances_total())
                                   : fmt::format("{} {}/{}", p.stage(), p.instances_done(), p.instances_total());
  ImGui::SameLine();
  ImGui::ProgressBar(reading ? 1.0f : done, {-1, 0}, text.c_str());
}

}  // namespace

// Shown where the server names a PACS: search, a study's series, open one.
void PacsPanel(PacsBrowser& pacs) {
  SearchFields(pacs);
  StudiesTable(pacs);
  SeriesTable(pacs);
  OpenButton(pacs);
  if (ImGui::Button("Store measurements")) pacs.StoreMeasurements(pacs.query.pacs());
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("The session's measurements, as a DICOM SR in its study on this PACS");
  if (pacs.status.empty()) return;
  if (pacs.failed) ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.55f, 0.45f, 1.0f));
  ImGui::TextWrapped("%s", pacs.status.c_str());
  if (pacs.failed) ImGui::PopStyleColor();
}

}  // namespace cinevol::viewer

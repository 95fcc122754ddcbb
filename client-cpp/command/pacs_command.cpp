// `cinevol pacs list|search|series|load --server ADDR [--pacs NAME]`: the
// PACS a server names, studies and series in one, a series loaded as a volume.
// Tables for people, proto3 JSON (--json) for scripts.
#include <fmt/format.h>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "pacs_load.h"
#include "scene/scene_file.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct PacsOptions {
  ConnectionOptions connection;
  bool json = false;
  v1::SearchStudiesRequest search;  // search's fields; load's --patient-id
  std::string dates;                // --date FROM-TO
  std::string study, series, orientation, labels_for;
  std::string presentation, scene_out;  // load --presentation UID [--scene-out FILE]
  bool resample_uneven = false;
};

// "20240101-20241231", "20240101-" or "-20241231" into the request's range.
void SetDates(const std::string& dates, v1::SearchStudiesRequest& request) {
  if (dates.empty()) return;
  const std::size_t dash = dates.find('-');
  if (dash == std::string::npos) {
    request.set_study_date_from(dates);
    request.set_study_date_to(dates);
    return;
  }
  request.set_study_date_from(dates.substr(0, dash));
  request.set_study_date_to(dates.substr(dash + 1));
}

std::string Count(bool has, std::int64_t n) { return has ? std::to_string(n) : "-"; }

void List(const PacsOptions& o) {
  const std::vector<std::string> names = Connect(o.connection).ListPacs();
  if (o.json) {
    v1::ListPacsResponse response;
    response.mutable_names()->Assign(names.begin(), names.end());
    return PrintJson(response);
  }
  if (names.empty()) fmt::print("this server names no PACS (cinevol-server --pacs NAME=URL)\n");
  for (const std::string& name : names) fmt::print("{}\n", name);
}

void Search(const PacsOptions& o) {
  v1::SearchStudiesRequest request = o.search;
  SetDates(o.dates, request);
  const auto studies = Connect(o.connection).SearchStudies(request);
  if (o.json) {
    v1::SearchStudiesResponse response;
    response.mutable_studies()->Assign(studies.begin(), studies.end());
    return PrintJson(response);
  }
  std::vector<TextRow> rows{{"STUDY UID", "PATIENT", "PATIENT ID", "DATE", "MODALITIES", "SERIES", "DESCRIPTION"}};
  for (const v1::StudySummary& s : studies) {
    std::string modalities;
    for (const std::string& m : s.modalities()) modalities += (modalities.empty() ? "" : ",") + m;
    rows.push_back({s.study_uid(), s.patient_name(), s.patient_id(), s.study_date(), modalities,
                    Count(s.has_series_count(), s.series_count()), s.description()});
  }
  PrintTable(rows);
}

void Series(const PacsOptions& o) {
  const auto series = Connect(o.connection).SearchSeries(o.search.pacs(), o.study);
  if (o.json) {
    v1::SearchSeriesResponse response;
    response.mutable_series()->Assign(series.begin(), series.end());
    return PrintJson(response);
  }
  std::vector<TextRow> rows{{"SERIES UID", "MODALITY", "NUMBER", "INSTANCES", "DESCRIPTION"}};
  for (const v1::SeriesSummary& s : series) {
    rows.push_back({s.series_uid(), s.modality(), Count(s.has_series_number(), s.series_number()),
                    Count(s.has_instance_count(), s.instance_count()), s.description()});
  }
  PrintTable(rows);
}

// A presentation state's scene and the series it presents, loaded: the scene goes to --scene-out.
v1::LoadPresentationResponse LoadPresentation(Client& client, const PacsOptions& o, PacsLoad& load) {
  if (!o.search.patient_id().empty()) throw InputError("--presentation: give no --patient-id; the state names its series");
  v1::LoadPresentationRequest request;
  request.set_pacs(o.search.pacs());
  request.set_sop_instance_uid(o.presentation);
  request.set_study_uid(o.study);
  request.set_series_uid(o.series);
  v1::LoadPresentationResponse presentation = client.LoadPresentation(request);
  load.study = presentation.study_uid();
  load.series = presentation.series_uid();
  return presentation;
}

void Load(const PacsOptions& o) {
  Client client = Connect(o.connection);
  PacsLoad load{o.search.pacs(), o.study, o.search.patient_id(), o.series, o.orientation, o.resample_uneven,
                o.labels_for};
  std::optional<v1::LoadPresentationResponse> presentation;
  if (!o.presentation.empty()) presentation = LoadPresentation(client, o, load);
  const v1::VolumeInfo volume = LoadFromPacs(client, load, [&](const v1::LoadSeriesProgress& p) {
    if (!o.json) fmt::print(stderr, "{}: {} of {} instances, {}\n", p.stage(), p.instances_done(),
                            p.instances_total(), Bytes(p.bytes()));
  });
  if (presentation && !presentation->labels_series_uid().empty()) {  // the segments it shows: the volume's labels
    const PacsLoad labels{o.search.pacs(), load.study, "", presentation->labels_series_uid(), "", false, volume.id()};
    LoadFromPacs(client, labels, [](const v1::LoadSeriesProgress&) {});
  }
  if (presentation && !o.scene_out.empty()) SaveSceneFile(presentation->scene(), o.scene_out);
  if (o.json) return PrintJson(volume);
  PrintVolume(volume);
  if (presentation) {
    fmt::print("presentation state {}: {}{}\n", presentation->label(), presentation->description(),
               presentation->has_rendered()
                   ? fmt::format(" (rendered as instance {})", presentation->rendered().sop_instance_uid())
                   : "");
    if (!o.scene_out.empty()) {
      fmt::print("its scene: {} (cinevol snapshot --volume {} --scene {} --out still.png)\n", o.scene_out,
                 volume.id(), o.scene_out);
    }
  }
}

CLI::App* AddPacsSubcommand(CLI::App* pacs, const std::string& name, const std::string& help,
                            std::function<void(const PacsOptions&)> run, std::shared_ptr<PacsOptions>& o,
                            bool names_a_pacs = true) {
  auto* cmd = pacs->add_subcommand(name, help);
  o = std::make_shared<PacsOptions>();
  AddConnectionOptions(cmd, o->connection);
  AddCallTimeoutOption(cmd, o->connection);
  if (names_a_pacs) {
    cmd->add_option("--pacs", *o->search.mutable_pacs(), "The PACS by the name the server gives it (--pacs NAME=URL)")
        ->required();
  }
  cmd->add_flag("--json", o->json, "Print the server's answer as proto3 JSON (one object)");
  cmd->callback([o, run] { run(*o); });
  return cmd;
}

}  // namespace

void AddPacsCommand(CLI::App& app) {
  auto* pacs = app.add_subcommand("pacs", "Search the PACS a server names and load a series from one");
  pacs->require_subcommand(1);
  std::shared_ptr<PacsOptions> o;
  AddPacsSubcommand(pacs, "list", "The PACS the server names", List, o, false);
  auto* search = AddPacsSubcommand(pacs, "search", "Studies matching every field given", Search, o);
  search->add_option("--patient-id", *o->search.mutable_patient_id(), "Patient ID (DICOM wildcards * and ?)");
  search->add_option("--patient-name", *o->search.mutable_patient_name(), "Patient name, FAMILY^GIVEN (wildcards)");
  search->add_option("--modality", *o->search.mutable_modality(), "A modality in the study: CT, MR, ...");
  search->add_option("--date", o->dates, "Study date YYYYMMDD, or a range FROM-TO (either end may be open)");
  search->add_option("--accession", *o->search.mutable_accession_number(), "Accession number");
  search->add_option("--description", *o->search.mutable_study_description(), "Study description (wildcards)");

  auto* series = AddPacsSubcommand(pacs, "series", "The series of one study", Series, o);
  series->add_option("--study", o->study, "Study Instance UID")->required();

  auto* load = AddPacsSubcommand(pacs, "load", "Load a series as a volume: the study's largest unless --series",
                                 Load, o);
  load->add_option("--study", o->study, "Study Instance UID");
  load->add_option("--series", o->series, "Series Instance UID (default: the study's with the most instances)");
  load->add_option("--patient-id", *o->search.mutable_patient_id(), "Instead of --study: the patient's latest study");
  load->add_option("--orientation", o->orientation, "Where index axes x, y, z point, overriding the files' (LPS)");
  load->add_flag("--resample-uneven", o->resample_uneven, kResampleUnevenHelp);
  load->add_option("--presentation", o->presentation,
                   "A Volume Rendering Volumetric Presentation State's SOP Instance UID: loads the series it "
                   "presents (--study and --series may say where the state lies)");
  load->add_option("--scene-out", o->scene_out, "With --presentation: write the scene it presents to this file");
  load->add_option("--labels-for", o->labels_for,
                   "A volume you hold: --series is a DICOM SEG, loaded as that volume's labels");
}

}  // namespace cinevol::cli

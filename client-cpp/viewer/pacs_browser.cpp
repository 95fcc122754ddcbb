// The PACS browser's calls and what their answers show.
#include "viewer/pacs_browser.h"

#include <fmt/format.h>

#include <algorithm>

namespace cinevol::viewer {
namespace {

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

PacsBrowser::PacsBrowser(ViewerContext& context, SessionLink& link, OpenVolume open_volume)
    : context_(context), link_(link), open_volume_(std::move(open_volume)) {}

void PacsBrowser::Forget() {
  ++generation_;
  busy_ = 0;
  opening = false;
  progress.reset();
}

void PacsBrowser::ListPacs() {
  link_.connection().Request(
      [this, generation = generation_](Client& client) {
        std::vector<std::string> listed = client.ListPacs();
        context_.ui.Later([this, generation, listed = std::move(listed)] {
          if (generation != generation_) return;
          names = listed;
          if (query.pacs().empty() && !names.empty()) query.set_pacs(names.front());
        });
      },
      [](const std::string&) {});  // a server without PACS, or older than them: no panel
}

void PacsBrowser::Call(const std::string& action, const std::string& pacs_name,
                       std::function<std::function<void()>(Client&)> call) {
  ++busy_;
  failed = false;
  link_.connection().Request(
      [this, action, pacs_name, call = std::move(call), generation = generation_](Client& client) {
        std::function<void()> then;
        try {
          then = call(client);
        } catch (const RpcError& e) {  // caught here rather than in Request's done, to keep the code
          then = [this, action, pacs_name, code = e.code(), text = std::string(e.what())] {
            Failed(action, pacs_name, code, text);
          };
        } catch (const std::exception& e) {
          then = [this, action, pacs_name, text = std::string(e.what())] {
            Failed(action, pacs_name, grpc::StatusCode::UNKNOWN, text);
          };
        }
        context_.ui.Later([this, generation, then = std::move(then)] {
          if (generation != generation_) return;  // the connection closed meanwhile
          --busy_;
          then();
        });
      },
      [](const std::string&) {});
}

void PacsBrowser::Failed(const std::string& action, const std::string& pacs_name, grpc::StatusCode code,
                         const std::string& message) {
  status = message;
  failed = true;
  if (action == "openSeries") {
    opening = false;
    progress.reset();
  }
  // The code alone: a message may quote what was asked, a patient's name or ID.
  google::protobuf::Struct report;
  (*report.mutable_fields())["pacs"] = TextValue(pacs_name);
  (*report.mutable_fields())["error"] = TextValue(StatusCodeName(code));
  context_.log.Report(action, report);
}

void PacsBrowser::Search(v1::SearchStudiesRequest request) {
  query = request;
  status = fmt::format("searching {}...", request.pacs());
  Call("searchPacs", request.pacs(), [this, request](Client& client) -> std::function<void()> {
    return [this, request, found = client.SearchStudies(request)] { ShowStudies(request, found); };
  });
}

void PacsBrowser::ShowStudies(const v1::SearchStudiesRequest& request, const std::vector<v1::StudySummary>& found) {
  source = request.pacs();
  studies = found;
  study_uid.clear();
  series.clear();
  series_uid.clear();
  const std::size_t page = request.limit() > 0 ? request.limit() : 50;  // the server's default page
  status = found.empty()       ? "no study matches"
           : found.size() == 1 ? "1 study"
                               : fmt::format("{} studies", found.size());
  if (found.size() >= page) status += " (a full page: narrow the search)";
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(request.pacs());
  auto& uids = *fields["studyUids"].mutable_list_value();
  for (const v1::StudySummary& s : found) *uids.add_values() = TextValue(s.study_uid());
  context_.log.Report("searchPacs", report);
}

void PacsBrowser::SelectStudy(const std::string& pacs_name, const std::string& uid) {
  source = pacs_name;
  study_uid = uid;
  series.clear();
  series_uid.clear();
  status = "listing the study's series...";
  Call("selectStudy", pacs_name, [this, pacs_name, uid](Client& client) -> std::function<void()> {
    std::vector<v1::SeriesSummary> listed = client.SearchSeries(pacs_name, uid);
    std::sort(listed.begin(), listed.end(),
              [](const auto& a, const auto& b) { return a.series_number() < b.series_number(); });
    return [this, pacs_name, uid, listed = std::move(listed)] { ShowSeries(pacs_name, uid, listed); };
  });
}

void PacsBrowser::ShowSeries(const std::string& pacs_name, const std::string& uid,
                             const std::vector<v1::SeriesSummary>& listed) {
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(pacs_name);
  fields["studyUid"] = TextValue(uid);
  auto& list = *fields["series"].mutable_list_value();
  for (const v1::SeriesSummary& s : listed) *list.add_values() = SeriesValue(s);
  context_.log.Report("selectStudy", report);
  if (study_uid != uid) return;  // another study was selected meanwhile
  series = listed;
  series_uid = LargestSeries(listed);  // Open takes it unless another is chosen
  status = listed.size() == 1 ? "1 series" : fmt::format("{} series", listed.size());
}

v1::LoadSeriesRequest PacsBrowser::SelectedSeries() const {
  v1::LoadSeriesRequest request;
  request.set_pacs(source);
  request.set_study_uid(study_uid);
  request.set_series_uid(series_uid);
  return request;
}

std::string PacsBrowser::ModalityOf(const std::string& series_uid) const {
  const auto it = std::find_if(series.begin(), series.end(),
                               [&](const v1::SeriesSummary& s) { return s.series_uid() == series_uid; });
  return it == series.end() ? "" : it->modality();
}

void PacsBrowser::OpenSeries(const v1::LoadSeriesRequest& images) {
  if (opening) {
    status = "a series is opening already: wait for it";
    return;
  }
  const std::string modality = ModalityOf(images.series_uid());
  if (modality == "SR") return OpenMeasurements(images);
  if (modality == "PR") return OpenPresentation(images);
  v1::LoadSeriesRequest request = images;
  if (modality == "SEG") {  // the labels of the volume looked at, in its frame of reference
    if (!link_.volume()) {
      status = "open the images this segmentation belongs to first";
      failed = true;
      return;
    }
    request.set_labels_for(link_.volume()->id());
  }
  opening = true;
  progress.reset();
  status = "opening the series...";
  // The server fetches and reads the series; its progress comes back meanwhile.
  Call("openSeries", request.pacs(), [this, request, generation = generation_](Client& client) {
    auto on_progress = [this, generation](const v1::LoadSeriesProgress& p) {
      context_.ui.Later([this, generation, p] {
        if (generation == generation_ && opening) progress = p;
      });
    };
    return std::function<void()>(
        [this, request, opened = client.LoadSeries(request, on_progress)] { Opened(request, opened); });
  });
}

void PacsBrowser::OpenPresentation(const v1::LoadSeriesRequest& series) {
  v1::LoadPresentationRequest request;
  request.set_pacs(series.pacs());
  request.set_study_uid(series.study_uid());
  request.set_series_uid(series.series_uid());
  opening = true;
  progress.reset();
  status = "reading the presentation state...";
  Call("openPresentation", request.pacs(), [this, request, generation = generation_](Client& client) {
    const v1::LoadPresentationResponse presented = client.LoadPresentation(request);
    v1::LoadSeriesRequest images;
    images.set_pacs(request.pacs());
    images.set_study_uid(presented.study_uid());
    images.set_series_uid(presented.series_uid());
    auto on_progress = [this, generation](const v1::LoadSeriesProgress& p) {
      context_.ui.Later([this, generation, p] {
        if (generation == generation_ && opening) progress = p;
      });
    };
    v1::VolumeInfo opened = client.LoadSeries(images, on_progress);
    if (!presented.labels_series_uid().empty()) {  // the SEG whose segments it styles: the volume's labels
      v1::LoadSeriesRequest labels = images;
      labels.set_series_uid(presented.labels_series_uid());
      labels.set_labels_for(opened.id());
      opened = client.LoadSeries(labels, on_progress);
    }
    return std::function<void()>([this, images, opened, scene = presented.scene()] { Opened(images, opened, scene); });
  });
}

void PacsBrowser::OpenMeasurements(const v1::LoadSeriesRequest& series) {
  v1::LoadMeasurementsRequest request;
  request.set_pacs(series.pacs());
  request.set_study_uid(series.study_uid());
  request.set_series_uid(series.series_uid());
  status = "reading the measurement report...";
  Call("openMeasurements", request.pacs(), [this, request](Client& client) -> std::function<void()> {
    const v1::LoadMeasurementsResponse report = client.LoadMeasurements(request);
    return [this, report] {
      link_.shown().SetMeasurements({report.measurements().begin(), report.measurements().end()});
      status = fmt::format("{} measurement(s) from the report", report.measurements_size());
      google::protobuf::Struct said;
      (*said.mutable_fields())["measurements"] = NumberValue(report.measurements_size());
      context_.log.Report("openMeasurements", said);
    };
  });
}

void PacsBrowser::StoreMeasurements(const std::string& pacs_name) {
  const std::string session_id = link_.session_id();
  if (session_id.empty()) {
    status = "no session is open: there is nothing to store";
    failed = true;
    return;
  }
  status = fmt::format("storing the measurements on {}...", pacs_name);
  Call("storeMeasurements", pacs_name, [this, session_id, pacs_name](Client& client) -> std::function<void()> {
    const v1::StoredObject stored = client.StoreMeasurements(session_id, pacs_name);
    return [this, stored] {
      status = fmt::format("measurements stored on {}: series {}", stored.pacs(), stored.series_uid());
      google::protobuf::Struct said;
      (*said.mutable_fields())["pacs"] = TextValue(stored.pacs());
      (*said.mutable_fields())["seriesUid"] = TextValue(stored.series_uid());
      context_.log.Report("storeMeasurements", said);
    };
  });
}

void PacsBrowser::Opened(const v1::LoadSeriesRequest& request, const v1::VolumeInfo& opened,
                         std::optional<v1::Scene> scene) {
  opening = false;
  progress.reset();
  status = fmt::format("opened {} ({} x {} x {})", opened.id(), opened.dims().x(), opened.dims().y(), opened.dims().z());
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields["pacs"] = TextValue(request.pacs());
  fields["studyUid"] = TextValue(request.study_uid());
  fields["seriesUid"] = TextValue(request.series_uid());
  fields["volumeId"] = TextValue(opened.id());
  fields["source"] = TextValue(opened.source());
  if (scene) fields["presentation"].set_bool_value(true);  // opened in a presentation state's scene
  context_.log.Report("openSeries", report);
  open_volume_(opened.id(), std::move(scene));  // as a click on one of the server's volumes does
}

}  // namespace cinevol::viewer

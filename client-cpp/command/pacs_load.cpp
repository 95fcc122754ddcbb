// LoadFromPacs: the study and series a user means, then LoadSeries.
#include "pacs_load.h"

#include <fmt/format.h>

#include <algorithm>

#include "core/error.h"

namespace cinevol::cli {
namespace {

// The patient's latest study (by date).
std::string LatestStudy(Client& client, const PacsLoad& load) {
  v1::SearchStudiesRequest request;
  request.set_pacs(load.pacs);
  request.set_patient_id(load.patient_id);
  const auto studies = client.SearchStudies(request);
  if (studies.empty()) {
    throw InputError(fmt::format("--patient-id: no study of '{}' in PACS '{}'", load.patient_id, load.pacs));
  }
  return std::max_element(studies.begin(), studies.end(), [](const auto& a, const auto& b) {
           return a.study_date() < b.study_date();
         })->study_uid();
}

// The study's series with the most instances.
std::string LargestSeries(Client& client, const std::string& pacs, const std::string& study) {
  const auto series = client.SearchSeries(pacs, study);
  if (series.empty()) throw InputError(fmt::format("--study: study {} has no series in PACS '{}'", study, pacs));
  return std::max_element(series.begin(), series.end(), [](const auto& a, const auto& b) {
           return a.instance_count() < b.instance_count();
         })->series_uid();
}

}  // namespace

v1::VolumeInfo LoadFromPacs(Client& client, const PacsLoad& load,
                            const std::function<void(const v1::LoadSeriesProgress&)>& progress) {
  if (load.study.empty() == load.patient_id.empty()) {
    throw InputError("give --study UID (with --series UID or not) or --patient-id ID, one of them");
  }
  if (!load.labels_for.empty() && load.series.empty()) {
    throw InputError("--labels-for needs --series: the DICOM SEG series to load as the volume's labels");
  }
  v1::LoadSeriesRequest request;
  request.set_pacs(load.pacs);
  request.set_study_uid(load.study.empty() ? LatestStudy(client, load) : load.study);
  request.set_series_uid(load.series.empty() ? LargestSeries(client, request.pacs(), request.study_uid()) : load.series);
  request.set_orientation(load.orientation);
  request.set_resample_uneven(load.resample_uneven);
  request.set_labels_for(load.labels_for);
  return client.LoadSeries(request, progress);
}

}  // namespace cinevol::cli

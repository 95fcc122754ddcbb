#include "pacs_calls.h"

#include "server_pool.h"

namespace cinevol {

PacsCalls::PacsCalls(ServerPool& pool, const std::string& server)
    : pool_(pool), stub_(v1::PacsService::NewStub(pool.Channel(server))) {}

std::vector<std::string> PacsCalls::Names() {
  v1::ListPacsResponse response;
  Check(stub_->ListPacs(pool_.CallContext().get(), {}, &response));
  return {response.names().begin(), response.names().end()};
}

std::vector<v1::StudySummary> PacsCalls::SearchStudies(const v1::SearchStudiesRequest& request) {
  v1::SearchStudiesResponse response;
  Check(stub_->SearchStudies(pool_.CallContext().get(), request, &response));
  return {response.studies().begin(), response.studies().end()};
}

std::vector<v1::SeriesSummary> PacsCalls::SearchSeries(const std::string& pacs, const std::string& study_uid) {
  v1::SearchSeriesRequest request;
  request.set_pacs(pacs);
  request.set_study_uid(study_uid);
  v1::SearchSeriesResponse response;
  Check(stub_->SearchSeries(pool_.CallContext().get(), request, &response));
  return {response.series().begin(), response.series().end()};
}

v1::VolumeInfo PacsCalls::LoadSeries(const v1::LoadSeriesRequest& request,
                                     const std::function<void(const v1::LoadSeriesProgress&)>& on_progress) {
  auto context = pool_.CallContext();
  auto reader = stub_->LoadSeries(context.get(), request);
  v1::LoadSeriesUpdate update;
  v1::VolumeInfo volume;
  while (reader->Read(&update)) {
    if (update.has_progress() && on_progress) on_progress(update.progress());
    if (update.has_volume()) volume = update.volume();
  }
  Check(reader->Finish());
  return volume;
}

v1::StoredObject PacsCalls::StoreMeasurements(const v1::StoreMeasurementsRequest& request) {
  v1::StoredObject response;
  Check(stub_->StoreMeasurements(pool_.CallContext().get(), request, &response));
  return response;
}

v1::LoadMeasurementsResponse PacsCalls::LoadMeasurements(const v1::LoadMeasurementsRequest& request) {
  v1::LoadMeasurementsResponse response;
  Check(stub_->LoadMeasurements(pool_.CallContext().get(), request, &response));
  return response;
}

v1::LoadPresentationResponse PacsCalls::LoadPresentation(const v1::LoadPresentationRequest& request) {
  v1::LoadPresentationResponse response;
  Check(stub_->LoadPresentation(pool_.CallContext().get(), request, &response));
  return response;
}

v1::SliceImage PacsCalls::RenderFrame(const v1::RenderFrameRequest& request) {
  v1::SliceImage response;
  Check(stub_->RenderFrame(pool_.CallContext().get(), request, &response));
  return response;
}

}  // namespace cinevol

// The PACS calls, to one server of a ServerPool: what Client's PACS methods
// send to its home server, and what failover sends to another to load a
// series there again.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"

namespace cinevol {

class ServerPool;

class PacsCalls {
 public:
  PacsCalls(ServerPool& pool, const std::string& server);

  std::vector<std::string> Names();
  std::vector<v1::StudySummary> SearchStudies(const v1::SearchStudiesRequest& request);
  std::vector<v1::SeriesSummary> SearchSeries(const std::string& pacs, const std::string& study_uid);
  // Progress as the server sends it, then the volume.
  v1::VolumeInfo LoadSeries(const v1::LoadSeriesRequest& request,
                            const std::function<void(const v1::LoadSeriesProgress&)>& on_progress = {});
  v1::StoredObject StoreMeasurements(const v1::StoreMeasurementsRequest& request);
  v1::LoadMeasurementsResponse LoadMeasurements(const v1::LoadMeasurementsRequest& request);
  v1::LoadPresentationResponse LoadPresentation(const v1::LoadPresentationRequest& request);
  v1::SliceImage RenderFrame(const v1::RenderFrameRequest& request);

 private:
  ServerPool& pool_;
  std::unique_ptr<v1::PacsService::Stub> stub_;
};

}  // namespace cinevol

// FetchFramePlane (frame_plane.h): the instance's WADO-RS metadata, apart from
// FramePlaneOf's parsing, which needs no network (the fuzzers link it alone).
#include <fmt/format.h>

#include "pacs/dicomweb_requests.h"
#include "pacs/frame_plane.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {

FramePlane FetchFramePlane(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                           const std::string& instance_uid, int frame, const std::atomic<bool>* cancel) {
  CheckUid(instance_uid, "sop_instance_uid");
  const PacsConfig& config = pacs.config();
  const std::string what = fmt::format("the metadata of instance {}", instance_uid);
  JsonDocument storage;
  const std::vector<DicomJsonDataset> datasets = FetchDicomJson(
      config, what, SeriesUrl(config, study_uid, series_uid) + "/instances/" + instance_uid + "/metadata", cancel,
      storage);
  if (datasets.empty()) {
    throw PacsError(fmt::format("PACS '{}' holds no instance {} in that series", config.name, instance_uid), 404);
  }
  return FramePlaneOf(datasets.front(), frame);
}

}  // namespace cinevol::pacs

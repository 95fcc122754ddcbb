// A series from a PACS becomes a volume: the PACS lists its instances, the
// memory the volume will take is checked against the caller's limits from
// that listing (instances x rows x columns), the instances are fetched in
// parallel into a private scratch folder, and the reader cage reads them
// there as it reads any DICOM folder. Nothing from the PACS is parsed in the
// server process but its search answers (DICOM JSON, pacs/dicom_json.h).
#pragma once

#include <atomic>
#include <functional>

#include "cinevol/v1/service.pb.h"
#include "pacs/dicomweb_client.h"
#include "runtime/principal.h"
#include "runtime/volume_registry.h"

namespace cinevol::service {

using SeriesProgress = std::function<void(const v1::LoadSeriesProgress&)>;

// Run it off the gRPC threads: seconds to minutes. A series the caller
// already holds is answered at once. `cancel` stops it within a second.
// With labels_for, the series is a DICOM SEG: fetched the same way, read in
// the reader cage as that volume's segmentation (io/dicom_seg.h), and the
// answer is that volume.
v1::VolumeInfo LoadSeries(const pacs::DicomWebClient& pacs, VolumeRegistry& volumes,
                          const v1::LoadSeriesRequest& request, const Principal& caller,
                          const std::atomic<bool>* cancel, const SeriesProgress& progress);

}  // namespace cinevol::service

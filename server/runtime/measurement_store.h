// Measurements sent back and brought in (issue 57): a session's measurements stored into the study of its volume's
// series as a DICOM SR measurement report (pacs/measurement_report.h), and a report on a PACS read back as
// measurements for a session.
#pragma once

#include <atomic>
#include <string>

#include "cinevol/v1/service.pb.h"
#include "core/volume.h"
#include "pacs/dicomweb_client.h"
#include "runtime/render_store.h"

namespace cinevol::service {

// Where the volume a session measures came from (`info`, `metadata`), for a report stored into its study.
// FAILED_PRECONDITION when it did not come from a PACS, or was read with its orientation overridden (its patient
// coordinates are then not those of the series' frame of reference).
PacsOrigin MeasuredOrigin(const v1::VolumeInfo& info, const VolumeMetadata& metadata);

// Stores `measurements` (patient coordinates of the volume loaded from `origin`) on `to` as a Comprehensive 3D SR
// in `origin`'s study, whose patient and study attributes, images and frame of reference `from` (the source PACS)
// answers (`frame`: the one the volume's files named, may be empty; the PACS must agree); `version` is cinevol's.
// Throws PacsError, InputError (a measurement the report cannot hold), Cancelled.
v1::StoredObject StoreMeasurements(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from,
                                   const PacsOrigin& origin, const std::string& frame,
                                   const google::protobuf::RepeatedPtrField<v1::Measurement>& measurements,
                                   const std::string& version, const std::atomic<bool>* cancel);

// The report `request` names on `pacs` (its series' only instance where it names none), retrieved (WADO-RS, at
// most pacs::kMaxReportBytes) and read by cinevol's bounded parser, never by a library in this process. Throws
// InputError naming what is wrong with the request or the report, PacsError, Cancelled.
v1::LoadMeasurementsResponse LoadMeasurements(const pacs::DicomWebClient& pacs,
                                              const v1::LoadMeasurementsRequest& request,
                                              const std::atomic<bool>* cancel);

}  // namespace cinevol::service

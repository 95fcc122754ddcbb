// The DICOMweb requests a measurement report and a presentation state need beyond DicomWebClient's own: what their
// source series is (its frame of reference and images, QIDO-RS), and one instance's bytes in memory (WADO-RS), both
// bounded.
#pragma once

#include <atomic>
#include <cstddef>
#include <string>

#include "pacs/dicomweb_client.h"
#include "pacs/measurement_report.h"

namespace cinevol::pacs {

// QIDO-RS /studies/{s}/series/{se}/instances with includefield 00200052 and 00080016: the series' images (at most
// max_instances) and the Frame of Reference UID they share; where the listing leaves it out, `known_frame` (the
// one the volume read from the files), else WADO-RS metadata of one instance, says it. PacsError for a series
// whose instances name none or several, or another than `known_frame`; OverLimit past max_instances; InputError
// for a bad UID.
ReportSource DescribeSourceSeries(const DicomWebClient& pacs, const std::string& study_uid,
                                    const std::string& series_uid, const std::string& known_frame = {},
                                    const std::atomic<bool>* cancel = nullptr);

// WADO-RS metadata of one image: where it lies (ImagePlane). PacsError where the PACS's answer gives no plane (an
// image without one, or a multi-frame image, whose planes lie per frame); InputError for a bad UID.
ImagePlane FetchImagePlane(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                           const std::string& sop_instance_uid, const std::atomic<bool>* cancel = nullptr);

// Where an instance lies: its study and series.
struct InstanceLocation {
  std::string study_uid;
  std::string series_uid;
};

// QIDO-RS /instances?SOPInstanceUID=...: the study and series of the instance, by its UID alone. PacsError (404)
// where the PACS holds none, or answers with more than one place or UIDs that are not UIDs; InputError for a bad UID.
InstanceLocation FindInstance(const DicomWebClient& pacs, const std::string& sop_instance_uid,
                              const std::atomic<bool>* cancel = nullptr);

// WADO-RS /studies/{s}/series/{se}/instances/{i}, as stored: the one DICOM Part 10 instance the answer holds, at
// most `max_bytes` (InputError past it, naming the limit). PacsError for a failing PACS or a malformed answer.
std::string RetrieveInstance(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                             const std::string& sop_instance_uid, std::size_t max_bytes,
                             const std::atomic<bool>* cancel = nullptr);

}  // namespace cinevol::pacs

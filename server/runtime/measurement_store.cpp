// StoreMeasurements and LoadMeasurements: the study and series asked of the PACS, the report made or read, STOW-RS
// and WADO-RS.
#include "runtime/measurement_store.h"

#include <fmt/format.h>

#include <map>

#include "core/error.h"
#include "core/log_safe.h"
#include "pacs/dicom_json.h"
#include "pacs/measurement_report.h"
#include "pacs/measurement_requests.h"
#include "pacs/pacs_error.h"
#include "runtime/errors.h"

namespace cinevol::service {

PacsOrigin MeasuredOrigin(const v1::VolumeInfo& volume, const VolumeMetadata& metadata) {
  const PacsOrigin origin = OriginOf(
      volume, "measurements go back into the study of a series loaded with LoadSeries, in its frame of reference");
  // Resampling (uneven gaps, a tilt) keeps the files' patient coordinates; an orientation given over the files' moves
  // them.
  if (!metadata.orientation_override.empty()) {
    throw RpcError::FailedPrecondition(
        fmt::format("volume '{}' was read with its orientation overridden (@{}): its patient coordinates are not "
                    "those of the series' frame of reference, so its measurements cannot be stored in it",
                    volume.id(), LogSafe(metadata.orientation_override, 16)));
  }
  return origin;
}

v1::StoredObject StoreMeasurements(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from,
                                   const PacsOrigin& origin, const std::string& frame,
                                   const google::protobuf::RepeatedPtrField<v1::Measurement>& measurements,
                                   const std::string& version, const std::atomic<bool>* cancel) {
  std::vector<pacs::ReportMeasurement> report;
  for (const v1::Measurement& m : measurements) {
    pacs::ReportMeasurement& r = report.emplace_back();
    r.name = m.name();
    for (const v1::Vec3& p : m.points()) r.points.push_back({p.x(), p.y(), p.z()});
  }
  const pacs::SourceStudy study = StudyOf(from, origin, cancel);
  const pacs::ReportSource source =
      pacs::DescribeSourceSeries(from, origin.study_uid, origin.series_uid, frame, cancel);
  pacs::MeasurementReportUids uids;
  const std::string bytes = pacs::MakeMeasurementReport(study, source, report, version, &uids);
  to.StoreInstances(uids.study_uid, {bytes}, cancel);
  return StoredObjectOf(to, uids.study_uid, uids.series_uid, uids.sop_instance_uid);
}

namespace {

// Measurements a report made on images in their pixels, put in patient coordinates with each image's plane (WADO-RS
// metadata, once an image: at most one fetch a measurement), all in one frame of reference with its 3D ones.
void PlaceOnImages(const pacs::DicomWebClient& pacs, const std::string& study_uid, pacs::ReadReport& read,
                   const std::atomic<bool>* cancel) {
  std::map<std::string, pacs::ImagePlane> planes;
  for (pacs::ReportMeasurement& m : read.measurements) {
    if (m.image_uid.empty()) continue;
    if (m.image_series_uid.empty()) {
      throw InputError(
          fmt::format("measurement '{}' lies on image {}, which the report's evidence places in no "
                      "series",
                      m.name, m.image_uid));
    }
    auto it = planes.find(m.image_uid);
    if (it == planes.end()) {
      const std::string& study = m.image_study_uid.empty() ? study_uid : m.image_study_uid;
      it = planes.emplace(m.image_uid, pacs::FetchImagePlane(pacs, study, m.image_series_uid, m.image_uid, cancel))
               .first;
    }
    const std::string& frame = it->second.frame_of_reference_uid;
    if (!pacs::IsValidUid(frame)) {
      throw pacs::PacsError(
          fmt::format("PACS '{}': image {} names no Frame of Reference UID", pacs.config().name, m.image_uid));
    }
    if (read.frame_of_reference_uid.empty()) read.frame_of_reference_uid = frame;
    if (frame != read.frame_of_reference_uid) {
      throw InputError(
          fmt::format("measurement '{}' lies on an image in frame of reference {}, others in {}; "
                      "cinevol reads a report in one",
                      m.name, frame, read.frame_of_reference_uid));
    }
    pacs::PlaceOnImage(m, it->second);
  }
}

}  // namespace

v1::LoadMeasurementsResponse LoadMeasurements(const pacs::DicomWebClient& pacs,
                                              const v1::LoadMeasurementsRequest& request,
                                              const std::atomic<bool>* cancel) {
  pacs::CheckUid(request.study_uid(), "study_uid");
  pacs::CheckUid(request.series_uid(), "series_uid");
  std::string instance = request.sop_instance_uid();
  if (instance.empty()) {
    const std::vector<pacs::InstanceSummary> listed =
        pacs.ListInstances(request.study_uid(), request.series_uid(), cancel);
    if (listed.size() != 1) {
      throw InputError(fmt::format("sop_instance_uid: series {} holds {} instances; name the report",
                                   request.series_uid(), listed.size()));
    }
    instance = listed.front().sop_instance_uid;
  }
  pacs::ReadReport read = pacs::ReadMeasurementReport(
      pacs::RetrieveInstance(pacs, request.study_uid(), request.series_uid(), instance, pacs::kMaxReportBytes, cancel));
  if (read.uids.sop_instance_uid != instance) {
    throw pacs::PacsError(
        fmt::format("PACS '{}' answered a retrieve of report {} with another instance", pacs.config().name, instance));
  }
  PlaceOnImages(pacs, request.study_uid(), read, cancel);
  v1::LoadMeasurementsResponse response;
  for (const pacs::ReportMeasurement& m : read.measurements) {
    v1::Measurement* out = response.add_measurements();
    out->set_name(m.name);
    for (const auto& p : m.points) {
      v1::Vec3* point = out->add_points();
      point->set_x(float(p[0]));
      point->set_y(float(p[1]));
      point->set_z(float(p[2]));
    }
  }
  response.set_frame_of_reference_uid(read.frame_of_reference_uid);
  response.set_source_series_uid(read.source_series_uid);
  return response;
}

}  // namespace cinevol::service

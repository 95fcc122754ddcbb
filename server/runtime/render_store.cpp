// StoreRender: the study's attributes, the capture, STOW-RS.
#include "runtime/render_store.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include "core/error.h"
#include "core/log_safe.h"
#include "encode/image_codecs.h"
#include "pacs/pacs_error.h"
#include "pacs/measurement_requests.h"
#include "pacs/secondary_capture.h"
#include "runtime/errors.h"
#include "runtime/presentation_store.h"
#include "scene/presets.h"

namespace cinevol::service {

std::string PacsSource(const PacsOrigin& origin, const std::string& suffix) {
  return fmt::format("pacs:{}/{}/{}{}", origin.pacs, origin.study_uid, origin.series_uid, suffix);
}

std::optional<PacsOrigin> ParsePacsSource(const std::string& source) {
  constexpr std::string_view kPrefix = "pacs:";
  if (source.rfind(kPrefix, 0) != 0) return std::nullopt;
  std::string rest = source.substr(kPrefix.size());
  rest = rest.substr(0, rest.find('@'));
  const std::size_t first = rest.find('/'), second = rest.find('/', first + 1);
  if (first == std::string::npos || second == std::string::npos) return std::nullopt;
  return PacsOrigin{rest.substr(0, first), rest.substr(first + 1, second - first - 1), rest.substr(second + 1)};
}

PacsOrigin OriginOf(const v1::VolumeInfo& volume, std::string_view why, std::string_view field) {
  const std::optional<PacsOrigin> origin = ParsePacsSource(volume.source());
  if (!origin) {
    throw RpcError::FailedPrecondition(fmt::format("{}volume '{}' did not come from a PACS (it is {}); {}", field,
                                                   volume.id(), LogSafe(volume.source(), 80), why));
  }
  return *origin;
}

pacs::SourceStudy StudyOf(const pacs::DicomWebClient& from, const PacsOrigin& origin,
                          const std::atomic<bool>* cancel) {
  pacs::StudyQuery query;
  query.study_uid = origin.study_uid;
  query.limit = 1;
  const std::vector<pacs::StudySummary> found = from.SearchStudies(query, cancel);
  if (found.empty() || found[0].study_uid != origin.study_uid) {
    throw pacs::PacsError(fmt::format("PACS '{}' no longer holds study {}: nothing can go back into it",
                                      origin.pacs, origin.study_uid), 404);
  }
  const pacs::StudySummary& s = found[0];
  pacs::SourceStudy study;
  study.patient_name = s.patient_name;
  study.patient_id = s.patient_id;
  study.patient_birth_date = s.patient_birth_date;
  study.patient_sex = s.patient_sex;
  study.study_uid = s.study_uid;
  study.study_id = s.study_id;
  study.study_date = s.study_date;
  study.study_time = s.study_time;
  study.accession_number = s.accession_number;
  study.referring_physician = s.referring_physician;
  study.study_description = s.description;
  study.series_uid = origin.series_uid;
  return study;
}

namespace {

// The SEG the volume's labels came from, where it is a series of the study on the same PACS (its one instance).
std::optional<SegSource> SegOf(const pacs::DicomWebClient& from, const PacsOrigin& origin,
                               const std::string& labels_source, const std::atomic<bool>* cancel) {
  const std::optional<PacsOrigin> seg = ParsePacsSource(labels_source);
  if (!seg || seg->pacs != origin.pacs || seg->study_uid != origin.study_uid) return std::nullopt;
  const std::vector<pacs::InstanceSummary> instances = from.ListInstances(seg->study_uid, seg->series_uid, cancel);
  if (instances.size() != 1) return std::nullopt;
  return SegSource{instances.front().sop_instance_uid, seg->series_uid};
}

}  // namespace

void StoreRender(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from, const PacsOrigin& origin,
                 v1::SnapshotResponse& still, const v1::Scene& scene, const Volume& volume,
                 const std::string& labels_source, const std::string& version, const std::atomic<bool>* cancel) {
  const ImageRgb8 image = DecodePng({still.image().begin(), still.image().end()});
  // The recipe is the scene as a scene file says it: in patient coordinates
  // (frame PATIENT_LPS, so it does not depend on how a reader centres the
  // volume), with the still's samples per pixel, not the session's per frame.
  v1::Scene recipe_scene = scene;
  ToPatientFrame(recipe_scene, VolumePlacement::Of(volume));
  recipe_scene.mutable_render()->set_spp(still.spp());
  recipe_scene.mutable_render()->set_width(still.width());
  recipe_scene.mutable_render()->set_height(still.height());
  pacs::RenderRecipe recipe;
  google::protobuf::util::JsonPrintOptions options;
  if (!google::protobuf::util::MessageToJsonString(recipe_scene, &recipe.scene_json, options).ok()) {
    throw std::runtime_error("the scene could not be written as JSON for the recipe");
  }
  recipe.source_series_uid = origin.series_uid;
  recipe.cinevol_version = version;
  recipe.preset = scene.transfer_function().preset();
  const pacs::SourceStudy study = StudyOf(from, origin, cancel);
  pacs::SecondaryCaptureUids capture_uids;
  const pacs::SecondaryCaptureImage pixels{image.width, image.height, image.bytes};
  std::vector<std::string> instances{pacs::MakeSecondaryCapture(study, pixels, recipe, &capture_uids)};

  // Beside it, the presentation state that renders it again, where the volume's patient coordinates are the
  // series' (not where a load overrode its orientation).
  pacs::PresentationStateUids presentation_uids;
  if (volume.metadata().orientation_override.empty()) {
    *recipe_scene.mutable_transfer_function() = ExpandTransferFunction(scene.transfer_function(), volume);
    pacs::PresentationState state =
        PresentationOf(recipe_scene, volume, SegOf(from, origin, labels_source, cancel));
    state.rendered_sop_class_uid = pacs::kSecondaryCaptureSopClass;
    state.rendered_sop_instance_uid = capture_uids.sop_instance_uid;
    state.rendered_series_uid = capture_uids.series_uid;
    const pacs::ReportSource source = pacs::DescribeSourceSeries(from, origin.study_uid, origin.series_uid,
                                                                 volume.metadata().frame_of_reference_uid, cancel);
    instances.push_back(pacs::MakePresentationState(study, source, state, version, &presentation_uids));
  }
  to.StoreInstances(capture_uids.study_uid, instances, cancel);
  *still.mutable_stored() = StoredObjectOf(to, capture_uids.study_uid, capture_uids.series_uid,
                                           capture_uids.sop_instance_uid);
  if (!presentation_uids.sop_instance_uid.empty()) {
    *still.mutable_presentation() = StoredObjectOf(to, presentation_uids.study_uid, presentation_uids.series_uid,
                                                   presentation_uids.sop_instance_uid);
  }
}

v1::StoredObject StoredObjectOf(const pacs::DicomWebClient& to, const std::string& study_uid,
                                const std::string& series_uid, const std::string& sop_instance_uid) {
  v1::StoredObject stored;
  stored.set_pacs(to.config().name);
  stored.set_study_uid(study_uid);
  stored.set_series_uid(series_uid);
  stored.set_sop_instance_uid(sop_instance_uid);
  return stored;
}

v1::StoredObject StoreMovie(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from,
                            const PacsOrigin& origin, const pacs::MovieStream& movie, const std::string& version,
                            const std::atomic<bool>* cancel) {
  pacs::SecondaryCaptureUids uids;
  const std::string bytes = pacs::MakeMovieCapture(StudyOf(from, origin, cancel), movie, version, &uids);
  to.StoreInstances(uids.study_uid, {bytes}, cancel);
  return StoredObjectOf(to, uids.study_uid, uids.series_uid, uids.sop_instance_uid);
}

}  // namespace cinevol::service

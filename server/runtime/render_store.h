// Renders sent back: a still of a volume that came from a PACS, stored into
// the source's study as a DICOM Secondary Capture (pacs/secondary_capture.h)
// with its recipe, so a picture in the report can be rendered again.
#pragma once

#include <atomic>
#include <optional>
#include <string>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "pacs/dicomweb_client.h"
#include "pacs/secondary_capture.h"
#include "scene/scene_frame.h"

namespace cinevol::service {

// Where a volume loaded from a PACS came from; as a volume's source it reads
// "pacs:NAME/STUDY_UID/SERIES_UID", with "@ORIENTATION" when one was given.
struct PacsOrigin {
  std::string pacs, study_uid, series_uid;
};
// "pacs:NAME/STUDY/SERIES" and `suffix`, how it was read (ReadChoices::Suffix).
std::string PacsSource(const PacsOrigin& origin, const std::string& suffix);
// Nothing for a source that is not a PACS's.
std::optional<PacsOrigin> ParsePacsSource(const std::string& source);

// The patient and study attributes of `origin`'s study as `from` (its PACS)
// answers them (QIDO-RS), for an object sent back into it (a render, a
// measurement report); PacsError (404) where the PACS no longer holds it.
pacs::SourceStudy StudyOf(const pacs::DicomWebClient& from, const PacsOrigin& origin, const std::atomic<bool>* cancel);

// Stores one instance (`bytes`, made with these UIDs) on `to` with STOW-RS
// and says where it went.
v1::StoredObject StoreInstance(const pacs::DicomWebClient& to, const std::string& bytes, const std::string& study_uid,
                               const std::string& series_uid, const std::string& sop_instance_uid,
                               const std::atomic<bool>* cancel);

// Stores `still` (a PNG) on `to` in the study `origin` names, whose patient
// and study attributes `from` (the source PACS) answers; `scene` (the
// session's, volume-centred; `placement` moves it to patient coordinates)
// and `version` make the recipe. Throws PacsError, InputError, Cancelled.
v1::StoredObject StoreRender(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from,
                             const PacsOrigin& origin, const v1::SnapshotResponse& still, const v1::Scene& scene,
                             const VolumePlacement& placement, const std::string& version,
                             const std::atomic<bool>* cancel);

}  // namespace cinevol::service

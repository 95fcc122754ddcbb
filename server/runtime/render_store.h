// Renders sent back: a still of a volume that came from a PACS, stored into
// the source's study as a DICOM Secondary Capture (pacs/secondary_capture.h)
// with its recipe and a presentation state beside it, so a picture in the
// report can be rendered again, by cinevol or another viewer.
#pragma once

#include <atomic>
#include <optional>
#include <string>
#include <string_view>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "pacs/dicomweb_client.h"
#include "pacs/secondary_capture.h"
#include "pacs/video_capture.h"
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
// Where `volume` came from, for an object that goes back into its study; FAILED_PRECONDITION "<field>volume 'ID'
// did not come from a PACS (it is SOURCE); <why>" for a volume from elsewhere.
PacsOrigin OriginOf(const v1::VolumeInfo& volume, std::string_view why, std::string_view field = {});

// The patient and study attributes of `origin`'s study as `from` (its PACS)
// answers them (QIDO-RS), for an object sent back into it (a render, a
// measurement report); PacsError (404) where the PACS no longer holds it.
pacs::SourceStudy StudyOf(const pacs::DicomWebClient& from, const PacsOrigin& origin, const std::atomic<bool>* cancel);

// Where an instance stored on `to` went.
v1::StoredObject StoredObjectOf(const pacs::DicomWebClient& to, const std::string& study_uid,
                                const std::string& series_uid, const std::string& sop_instance_uid);

// Stores `still` (a PNG) on `to` in the study `origin` names, whose patient
// and study attributes, images and frame of reference `from` (the source PACS)
// answers: a Secondary Capture with its recipe (`scene`, the session's,
// volume-centred, of `volume`; `version`), and beside it, in the same STOW-RS,
// a Volume Rendering Volumetric Presentation State that renders it again
// (presentation_store.h; not where the volume's orientation was overridden,
// as its patient coordinates are then not the series'), its label styles
// through the DICOM SEG the labels came from where that is a series of the
// same study (`labels_source`, VolumeInfo.labels.source). Sets
// `still.stored` and `still.presentation`. Throws PacsError, InputError,
// Cancelled.
void StoreRender(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from, const PacsOrigin& origin,
                 v1::SnapshotResponse& still, const v1::Scene& scene, const Volume& volume,
                 const std::string& labels_source, const std::string& version, const std::atomic<bool>* cancel);

// Stores `movie` (an H.264 stream) on `to` in the study `origin` names, as a
// DICOM Multi-frame True Color Secondary Capture (pacs/video_capture.h).
// Throws PacsError, InputError, Cancelled.
v1::StoredObject StoreMovie(const pacs::DicomWebClient& to, const pacs::DicomWebClient& from,
                            const PacsOrigin& origin, const pacs::MovieStream& movie, const std::string& version,
                            const std::atomic<bool>* cancel);

}  // namespace cinevol::service

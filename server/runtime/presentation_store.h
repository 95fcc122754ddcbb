// Recipes as DICOM presentation states (issue 57): a scene said as a Volume Rendering Volumetric Presentation State
// (pacs/presentation_state.h) where the IOD has a place for it, and one read back as a scene.
//
// What goes where. The view (eye, look-at point, up, field of view), the crop box and clip planes (Volume
// Cropping), and the transfer function's colour and opacity (an RGBA palette over a window) are the standard's
// attributes, which any viewer reads. What the IOD has no place for (lights, materials, density scale, samples,
// seed, label styles) stays in cinevol's recipe, the whole scene in a private block. Read back, the standard's
// attributes win: the recipe fills in only what they do not say, and a part of the recipe (its camera, crop box,
// plane caps, transfer function) is taken whole only where it says the same as the standard's attributes, so a
// presentation state another system edited shows its edit.
#pragma once

#include <array>
#include <atomic>
#include <optional>

#include "cinevol/v1/scene.pb.h"
#include "cinevol/v1/service.pb.h"
#include "core/volume.h"
#include "pacs/dicomweb_client.h"
#include "pacs/presentation_state.h"
#include "scene/scene_frame.h"

namespace cinevol::service {

// The DICOM SEG a volume's labels came from (a series of the same study on the same PACS).
struct SegSource {
  std::string sop_instance_uid;
  std::string series_uid;
};

// What of `scene` a presentation state says. `scene` is in patient coordinates (frame PATIENT_LPS) with its transfer
// function as points (ExpandTransferFunction), its render size that of the still; `volume` is what it shows (its
// axes decide whether a crop box is a bounding box or six planes; its extent the far distance). Where the scene
// styles labels that came from `seg`, the segments through it (the Segmented kind): each visible style in its colour
// and opacity over the image's transfer function (a label's own transfer function stays in the recipe).
pacs::PresentationState PresentationOf(const v1::Scene& scene, const Volume& volume,
                                       const std::optional<SegSource>& seg = std::nullopt);

// The scene `read` presents, in patient coordinates (frame PATIENT_LPS, no volume). `volume_axes` are the input
// series' row and column directions (Image Orientation (Patient)), the axes of a bounding box. Throws InputError for
// what a cinevol scene cannot show (an orthographic view, more planes than a scene holds, a recipe that is not a
// scene).
v1::Scene SceneOf(const pacs::ReadPresentation& read, const std::array<double, 6>& volume_axes);

// The presentation state `request` names on `pacs` (by its UID alone: a QIDO-RS search of the PACS's instances),
// retrieved (WADO-RS, at most pacs::kMaxPresentationBytes), read by cinevol's bounded parser, and made a scene.
// Throws InputError naming what is wrong with the request or the object, PacsError, Cancelled.
v1::LoadPresentationResponse LoadPresentation(const pacs::DicomWebClient& pacs,
                                              const v1::LoadPresentationRequest& request,
                                              const std::atomic<bool>* cancel);

}  // namespace cinevol::service

// A render's recipe as a DICOM Volume Rendering Volumetric Presentation State (issue 57; PS3.3 A.80.2, PS3.4
// B.5.1.24 and FF): written with DCMTK's dcmdata beside the Secondary Capture it describes, and read back, from cinevol
// or another system, by cinevol's own bounded parser (part10_reader.h). Everything here is in the patient
// coordinates of the series' frame of reference, the presentation state's reference coordinate system.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "pacs/measurement_report.h"
#include "pacs/secondary_capture.h"

namespace cinevol::pacs {

// Volume Rendering Volumetric Presentation State Storage (PS3.4 B.5).
inline constexpr const char* kVolumeRenderingPresentationSopClass = "1.2.840.10008.5.1.4.1.1.11.9";
// ... and its Segmented kind: segments of a referenced DICOM SEG, each cropped by it and coloured by its own palette.
inline constexpr const char* kSegmentedVolumeRenderingPresentationSopClass = "1.2.840.10008.5.1.4.1.1.11.10";
inline constexpr const char* kSegmentationSopClass = "1.2.840.10008.5.1.4.1.1.66.4";
// The most segments one shows on its own.
inline constexpr std::size_t kMaxPresentationSegments = 64;
// Its series number: past the renders (kRenderSeriesNumber) and reports (kMeasurementSeriesNumber).
inline constexpr int kPresentationSeriesNumber = 9902;
// Entries of the RGBA palette a transfer function is sampled into.
inline constexpr int kPaletteEntries = 4096;
// The most cropping planes in one set, and cinevol reads from one in all: a crop box's six faces and a scene's six
// clip planes (scene.proto).
inline constexpr std::size_t kMaxPlanesInASet = 6;
inline constexpr std::size_t kMaxPresentationPlanes = 12;
inline constexpr std::size_t kMaxPresentationBytes = std::size_t{16} << 20;

using Vec3d = std::array<double, 3>;

// Volume Render Geometry (C.11.30): a perspective view.
struct RenderGeometry {
  Vec3d viewpoint{};  // the eye
  Vec3d look_at{};
  Vec3d up{};
  // Render Field of View: Xleft, Xright, Ytop, Ybottom at the far distance, then the near and far distances (mm).
  std::array<double, 6> field_of_view{};
  bool perspective = true;  // false: ORTHOGRAPHIC
};

// A plane as Volume Cropping writes it: Ax + By + Cz + D = 0, the normal (A, B, C) a unit vector pointing away from
// what is kept.
struct CroppingPlane {
  std::array<double, 4> plane{};
};

// Volume Cropping (C.11.24), applied to the whole volume (Global Crop).
struct Cropping {
  // BOUNDING_BOX: two opposite corners of a box along the volume's axes.
  std::optional<std::array<double, 6>> bounding_box;
  // OBLIQUE_PLANES, one cropping specification each: what is kept lies behind every plane.
  std::vector<std::vector<CroppingPlane>> plane_sets;
};

// Render Display (C.11.32): the input's values (after its modality rescale) windowed linearly onto the palette, whose
// entries are [0, 1] colours and opacities as 16-bit numbers (65535 = 1). An entry's alpha is the opacity of a
// sample one Sampling Step Size long (Volume Render Geometry), as a ray caster composites it.
struct Classification {
  double window_center = 0;  // the VOI window: [center - width/2, center + width/2] onto entries [0, N - 1]
  double window_width = 1;
  std::vector<std::array<std::uint16_t, 4>> rgba;  // N = kPaletteEntries entries: red, green, blue, alpha
  std::string description;                         // RGBA Transfer Function Description: the preset, say
  double sampling_step_mm = 1;                     // (0070,1607): the step an alpha is the opacity of; > 0
};

// Render Shading (C.11.31): a Phong model lit from one white light at infinity.
struct Shading {
  Vec3d light_direction{0, 0, -1};  // where the light travels; a unit vector
  double ambient = 0.3, diffuse = 0.7;
  double specular = 0.2;   // [0, 1]
  double shininess = 0.5;  // [0, 1]: 1 the smoothest
};

// One segment of the referenced SEG shown with its own palette (the image's, in its colour and opacity).
struct SegmentShown {
  std::uint16_t number = 0;  // Segment Number: the label value
  Classification palette;
};

// The segments a presentation state shows through a SEG (the Segmented Volume Rendering class): the image's
// classification for what no styled segment covers (where `show_unlisted`), each shown segment's own over it
// (B over A, in order), a styled segment not shown hidden.
struct Segmentation {
  std::string sop_instance_uid;       // the SEG
  std::string series_uid;
  std::vector<std::uint16_t> styled;  // taken out of the image's classification
  std::vector<SegmentShown> shown;
  bool show_unlisted = true;
};

// What a presentation state holds, as cinevol writes and reads it.
struct PresentationState {
  RenderGeometry geometry;
  Cropping cropping;
  Classification classification;
  // What a viewer without a path tracer can approximate cinevol's lighting and materials with.
  Shading shading;
  std::string label = "CINEVOL_RENDER";  // Content Label, CS: A-Z 0-9 _ and space, at most 16
  std::string description;               // Content Description, LO: at most 64 characters
  // Rendered Image Reference: the Secondary Capture stored with it (may be empty).
  std::string rendered_sop_class_uid;
  std::string rendered_sop_instance_uid;
  std::string rendered_series_uid;
  // Set: the Segmented Volume Rendering class, through the SEG it names.
  std::optional<Segmentation> segmentation;
  // cinevol's recipe (the scene as proto3 JSON) in a private block: what the IOD has no place for (lights,
  // materials, samples and seed). Empty for a presentation state another system wrote.
  std::string recipe_json;
};

struct PresentationStateUids {
  std::string study_uid;
  std::string series_uid;
  std::string sop_instance_uid;
};

// A DICOM Part 10 Volume Rendering Volumetric Presentation State, explicit VR little endian: patient and study
// copied from `study` (as a Secondary Capture copies them), a new PR series (9902, "cinevol presentation") and
// instance, one VOLUME input of `source`'s images in its frame of reference, global cropping, the view, one
// ONE_TO_RGBA classification with an sRGB ICC profile, shading, the rendered image, and the recipe. Throws InputError
// naming the field for a bad input (UIDs, the study's attributes, a geometry that is not finite, a view with no
// direction, a palette of the wrong size, a window of no width, too long a recipe).
std::string MakePresentationState(const SourceStudy& study, const ReportSource& source,
                                  const PresentationState& state, const std::string& version,
                                  PresentationStateUids* uids_out = nullptr);

// What ReadPresentationState finds, with where it applies.
struct ReadPresentation {
  PresentationState state;
  PresentationStateUids uids;
  std::string frame_of_reference_uid;
  std::string source_study_uid;   // the input's study (this one's unless the input's images lie in another)
  std::string source_series_uid;  // the input's series (Common Instance Reference)
  std::vector<std::string> input_images;  // its SOP Instance UIDs, at least one
};

// Reads a Volume Rendering Volumetric Presentation State (cinevol's or another system's) of one VOLUME input and one
// volume stream of one ONE_TO_RGBA component with a windowed palette: its geometry, global cropping, classification,
// rendered image and, where cinevol wrote it, the recipe. Throws InputError saying what is wrong: not Part 10 or
// beyond the parser's bounds, another SOP class, several inputs or streams (Segmented and Multiple Volume Rendering
// are not read), a missing Type 1 attribute, numbers that are not finite, a view with no direction, a palette that is
// not 16-bit RGBA of 2 to 65536 entries, more than kMaxPresentationPlanes planes.
ReadPresentation ReadPresentationState(std::string part10_bytes);

}  // namespace cinevol::pacs

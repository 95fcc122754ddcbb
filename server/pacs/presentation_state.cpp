// Volume Rendering Volumetric Presentation States: written with DCMTK's dcmdata, read with cinevol's own Part 10
// parser. The module and attribute names below are PS3.3's (A.80.2, C.11.22-C.11.32).
#include "pacs/presentation_state.h"

#include <dcmtk/config/osconfig.h>  // first, as DCMTK asks
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcvrut.h>
#include <fmt/format.h>
#include <lcms2.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>

#include "core/error.h"
#include "pacs/dcmtk_writing.h"
#include "pacs/dicom_json.h"
#include "pacs/part10_reader.h"

namespace cinevol::pacs {
namespace {

constexpr std::string_view kDocument = "the presentation state";
constexpr double kMaxCoordinate = 1e7;  // mm: a view or crop beyond any patient is refused
constexpr std::size_t kMaxRecipeBytes = kMaxSceneJsonBytes;
// The private block of the recipe, as a Secondary Capture's (secondary_capture.h).
const DcmTag kRecipeCreatorTag(kRecipeGroup, 0x0010, EVR_LO);
const DcmTag kRecipeTag(kRecipeGroup, 0x1000 | kRecipeElement, EVR_UT);

void Put(DcmItem& item, const DcmTagKey& tag, const std::string& value, const char* what) {
  Require(item.putAndInsertString(tag, value.c_str()), kDocument, what);
}

void PutDoubles(DcmItem& item, const DcmTagKey& tag, const double* values, std::size_t count, const char* what) {
  Require(item.putAndInsertFloat64Array(tag, values, unsigned(count)), kDocument, what);
}

void PutShort(DcmItem& item, const DcmTagKey& tag, std::uint16_t value, const char* what) {
  Require(item.putAndInsertUint16(tag, value), kDocument, what);
}

DcmItem& NewItem(DcmItem& parent, const DcmTagKey& sequence, const char* what) {
  DcmItem* item = nullptr;
  Require(parent.findOrCreateSequenceItem(sequence, item, -2), kDocument, what);  // -2: a new item at the end
  return *item;
}

void PutEmptySequence(DcmItem& item, const DcmTagKey& tag, const char* what) {
  Require(item.insertEmptyElement(tag), kDocument, what);
}

void PutReference(DcmItem& item, const std::string& sop_class, const std::string& sop_instance) {
  Put(item, DCM_ReferencedSOPClassUID, sop_class, "Referenced SOP Class UID");
  Put(item, DCM_ReferencedSOPInstanceUID, sop_instance, "Referenced SOP Instance UID");
}

// IEC 61966-2-1 sRGB, the colour space of the palette's colours (and of cinevol's tone-mapped output).
std::vector<Uint8> SrgbIccProfile() {
  cmsHPROFILE profile = cmsCreate_sRGBProfile();
  if (profile == nullptr) throw std::runtime_error("the presentation state: lcms2 made no sRGB profile");
  cmsUInt32Number size = 0;
  std::vector<Uint8> bytes;
  if (cmsSaveProfileToMem(profile, nullptr, &size) && size > 0) {
    bytes.resize(size);
    if (!cmsSaveProfileToMem(profile, bytes.data(), &size)) bytes.clear();
  }
  cmsCloseProfile(profile);
  if (bytes.empty()) throw std::runtime_error("the presentation state: lcms2 could not write the sRGB profile");
  if (bytes.size() % 2 == 1) bytes.push_back(0);  // OB values have even lengths
  return bytes;
}

// ---- Checks of what is written ----

void CheckFinite(const double* values, std::size_t count, const char* field) {
  for (std::size_t i = 0; i < count; ++i) {
    if (!std::isfinite(values[i]) || std::abs(values[i]) > kMaxCoordinate) {
      Refuse(field, "holds a number that is not finite or beyond +-1e7");
    }
  }
}

double Length(const Vec3d& v) { return std::hypot(v[0], v[1], v[2]); }

void CheckGeometry(const RenderGeometry& g) {
  CheckFinite(g.viewpoint.data(), 3, "geometry.viewpoint");
  CheckFinite(g.look_at.data(), 3, "geometry.look_at");
  CheckFinite(g.up.data(), 3, "geometry.up");
  CheckFinite(g.field_of_view.data(), 6, "geometry.field_of_view");
  const Vec3d view{g.look_at[0] - g.viewpoint[0], g.look_at[1] - g.viewpoint[1], g.look_at[2] - g.viewpoint[2]};
  if (!(Length(view) > 0)) Refuse("geometry", "looks at its own viewpoint");
  if (!(Length(g.up) > 0)) Refuse("geometry.up", "is no direction");
  const auto& f = g.field_of_view;
  if (!(f[0] < f[1]) || !(f[3] < f[2]) || !(0 < f[4] && f[4] < f[5])) {
    Refuse("geometry.field_of_view", "is not Xleft < Xright, Ybottom < Ytop, 0 < near < far");
  }
}

void CheckCropping(const Cropping& c) {
  if (c.bounding_box) CheckFinite(c.bounding_box->data(), 6, "cropping.bounding_box");
  for (const auto& set : c.plane_sets) {
    if (set.empty() || set.size() > kMaxPlanesInASet) {
      Refuse("cropping.plane_sets", fmt::format("holds a set of {} planes; 1 to {}", set.size(), kMaxPlanesInASet));
    }
    for (const CroppingPlane& p : set) {
      CheckFinite(p.plane.data(), 4, "cropping.plane_sets");
      if (std::abs(std::hypot(p.plane[0], p.plane[1], p.plane[2]) - 1) > 1e-6) {
        Refuse("cropping.plane_sets", "holds a plane whose normal is not a unit vector");
      }
    }
  }
}

void CheckClassification(const Classification& c) {
  if (c.rgba.size() != std::size_t(kPaletteEntries)) {
    Refuse("classification.rgba", fmt::format("holds {} entries; {}", c.rgba.size(), kPaletteEntries));
  }
  if (!std::isfinite(c.window_center) || !std::isfinite(c.window_width) || !(c.window_width > 0)) {
    Refuse("classification.window", "is not a finite centre and a positive width");
  }
  if (!(c.sampling_step_mm > 0) || c.sampling_step_mm > kMaxCoordinate) {
    Refuse("classification.sampling_step_mm", "is not a positive length");
  }
}

void CheckShading(const Shading& s) {
  CheckFinite(s.light_direction.data(), 3, "shading.light_direction");
  if (std::abs(Length(s.light_direction) - 1) > 1e-6) Refuse("shading.light_direction", "is not a unit vector");
  for (const double v : {s.ambient, s.diffuse, s.specular, s.shininess}) {
    if (!(v >= 0 && v <= 1)) Refuse("shading", "has an intensity or shininess outside [0, 1]");
  }
}

void CheckSegmentation(const Segmentation& seg) {
  if (!IsValidUid(seg.sop_instance_uid) || !IsValidUid(seg.series_uid)) {
    Refuse("segmentation", "names a SEG whose UIDs are not DICOM UIDs");
  }
  if (seg.styled.empty() || seg.styled.size() > kMaxPresentationSegments) {
    Refuse("segmentation.styled", fmt::format("holds {} segments; 1 to {}", seg.styled.size(), kMaxPresentationSegments));
  }
  for (const SegmentShown& shown : seg.shown) {
    if (std::find(seg.styled.begin(), seg.styled.end(), shown.number) == seg.styled.end()) {
      Refuse("segmentation.shown", fmt::format("shows segment {}, which it does not style", shown.number));
    }
    CheckClassification(shown.palette);
  }
  if (!seg.show_unlisted && seg.shown.empty()) Refuse("segmentation", "shows nothing");
}

void CheckLabel(const std::string& label) {
  const bool cs = !label.empty() && label.size() <= 16 && std::all_of(label.begin(), label.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == ' ';
  });
  if (!cs) Refuse("label", "is not 1 to 16 of A-Z 0-9 _ and space (CS)");
}

// ---- Writing, module by module ----

void WriteSeriesAndEquipment(DcmDataset& d, const PresentationStateUids& uids, const std::string& frame,
                             const std::string& version, const DicomNow& now) {
  Put(d, DCM_Modality, "PR", "Modality");
  Put(d, DCM_SeriesInstanceUID, uids.series_uid, "Series Instance UID");
  Put(d, DCM_SeriesNumber, std::to_string(kPresentationSeriesNumber), "Series Number");
  Put(d, DCM_SeriesDescription, "cinevol presentation", "Series Description");
  Put(d, DCM_SeriesDate, now.date, "Series Date");
  Put(d, DCM_SeriesTime, now.time, "Series Time");
  Put(d, DCM_FrameOfReferenceUID, frame, "Frame of Reference UID");
  Put(d, DCM_PositionReferenceIndicator, "", "Position Reference Indicator");
  // Enhanced General Equipment: all four are Type 1.
  Put(d, DCM_Manufacturer, "cinevol", "Manufacturer");
  Put(d, DCM_ManufacturerModelName, "cinevol-server", "Manufacturer's Model Name");
  Put(d, DCM_DeviceSerialNumber, "none", "Device Serial Number");
  Put(d, DCM_SoftwareVersions, version, "Software Versions");
}

void WriteIdentification(DcmDataset& d, const PresentationState& s, const DicomNow& now) {
  Put(d, DCM_PresentationCreationDate, now.date, "Presentation Creation Date");
  Put(d, DCM_PresentationCreationTime, now.time, "Presentation Creation Time");
  Put(d, DCM_InstanceNumber, "1", "Instance Number");
  Put(d, DCM_ContentLabel, s.label, "Content Label");
  PutText(d, DCM_ContentDescription, "description", s.description, 64);
  if (!s.rendered_sop_instance_uid.empty()) {
    PutReference(NewItem(d, DCM_RenderedImageReferenceSequence, "Rendered Image Reference Sequence"),
                 s.rendered_sop_class_uid, s.rendered_sop_instance_uid);
  }
}

// One input of the volume and how it is cropped and classified.
struct Input {
  std::uint16_t crop = 0;  // its own Cropping Specification Number; 0: none
  const Classification* palette = nullptr;
};

// The volume's inputs: the image's classification, cropped by every segment the scene styles (EXCLUDE_SEG), then
// each segment shown, cropped to it (INCLUDE_SEG) with its own. Without a segmentation, the image's alone.
std::vector<Input> Inputs(const PresentationState& s, std::uint16_t first_specification) {
  if (!s.segmentation) return {{0, &s.classification}};
  std::vector<Input> inputs;
  std::uint16_t next = first_specification;
  const Segmentation& seg = *s.segmentation;
  if (seg.show_unlisted) inputs.push_back({seg.styled.empty() ? std::uint16_t(0) : next++, &s.classification});
  for (const SegmentShown& shown : seg.shown) inputs.push_back({next++, &shown.palette});
  return inputs;
}

void PutSegReference(DcmItem& spec, const Segmentation& seg, const std::vector<std::uint16_t>& segments) {
  DcmItem& reference = NewItem(spec, DCM_ReferencedImageSequence, "the SEG's reference");
  PutReference(reference, kSegmentationSopClass, seg.sop_instance_uid);
  Require(reference.putAndInsertUint16Array(DCM_ReferencedSegmentNumber, segments.data(), unsigned(segments.size())),
          kDocument, "Referenced Segment Number");
}

// The volume (the series' images) as the inputs above; the scene's crop box and planes crop every one (Global Crop).
void WriteRelationshipAndCropping(DcmDataset& d, const ReportSource& source, const PresentationState& s,
                                  const std::string& input_set_uid) {
  DcmItem& set = NewItem(d, DCM_VolumetricPresentationInputSetSequence, "Input Set Sequence");
  Put(set, DCM_VolumetricPresentationInputSetUID, input_set_uid, "Input Set UID");
  Put(set, DCM_PresentationInputType, "VOLUME", "Presentation Input Type");
  for (const ReportImage& image : source.images) {
    PutReference(NewItem(set, DCM_ReferencedImageSequence, "Referenced Image Sequence"), image.sop_class_uid,
                 image.sop_instance_uid);
  }
  std::vector<std::uint16_t> global;
  std::uint16_t specifications = 0;
  const auto specification = [&](const char* method) -> DcmItem& {
    DcmItem& item = NewItem(d, DCM_VolumeCroppingSequence, "Volume Cropping Sequence");
    PutShort(item, DCM_CroppingSpecificationNumber, ++specifications, "Cropping Specification Number");
    Put(item, DCM_VolumeCroppingMethod, method, "Volume Cropping Method");
    return item;
  };
  if (s.cropping.bounding_box) {
    PutDoubles(specification("BOUNDING_BOX"), DCM_BoundingBoxCrop, s.cropping.bounding_box->data(), 6,
               "Bounding Box Crop");
    global.push_back(specifications);
  }
  for (const std::vector<CroppingPlane>& planes : s.cropping.plane_sets) {
    DcmItem& item = specification("OBLIQUE_PLANES");
    for (const CroppingPlane& p : planes) {
      DcmItem& plane = NewItem(item, DCM_ObliqueCroppingPlaneSequence, "Oblique Cropping Plane Sequence");
      PutDoubles(plane, DCM_Plane, p.plane.data(), 4, "Plane");
      PutDoubles(plane, DCM_PlaneNormal, p.plane.data(), 3, "Plane Normal");
    }
    global.push_back(specifications);
  }
  const std::vector<Input> inputs = Inputs(s, std::uint16_t(specifications + 1));
  if (s.segmentation) {  // the specifications Inputs numbered, in its order
    const Segmentation& seg = *s.segmentation;
    if (seg.show_unlisted && !seg.styled.empty()) PutSegReference(specification("EXCLUDE_SEG"), seg, seg.styled);
    for (const SegmentShown& shown : seg.shown) PutSegReference(specification("INCLUDE_SEG"), seg, {shown.number});
  }
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    DcmItem& input = NewItem(d, DCM_VolumetricPresentationStateInputSequence, "Input Sequence");
    const Classification& c = *inputs[i].palette;
    PutShort(input, DCM_VolumetricPresentationInputNumber, std::uint16_t(i + 1), "Input Number");
    Put(input, DCM_VolumetricPresentationInputSetUID, input_set_uid, "Input Set UID");
    Put(input, DCM_WindowCenter, fmt::format("{:.10g}", c.window_center).substr(0, 16), "Window Center");
    Put(input, DCM_WindowWidth, fmt::format("{:.10g}", c.window_width).substr(0, 16), "Window Width");
    // The Volume Rendering class allows no input a crop of its own (PS3.4 B.5.1.24); the Segmented one crops by SEG.
    Put(input, DCM_Crop, inputs[i].crop == 0 ? "NO" : "YES", "Crop");
    if (inputs[i].crop != 0) PutShort(input, DCM_CroppingSpecificationIndex, inputs[i].crop, "Cropping Specification Index");
  }
  Put(d, DCM_GlobalCrop, global.empty() ? "NO" : "YES", "Global Crop");
  if (!global.empty()) {
    Require(d.putAndInsertUint16Array(DCM_GlobalCroppingSpecificationIndex, global.data(), unsigned(global.size())),
            kDocument, "Global Cropping Specification Index");
  }
}

void WriteViewAndGeometry(DcmDataset& d, const PresentationState& s) {
  // Presentation View Description: all Type 2, sent empty (cinevol does not code the anatomy it shows).
  PutEmptySequence(d, DCM_AnatomicRegionSequence, "Anatomic Region Sequence");
  PutEmptySequence(d, DCM_ViewCodeSequence, "View Code Sequence");
  Put(d, DCM_ImageLaterality, "", "Image Laterality");
  const RenderGeometry& g = s.geometry;
  Put(d, DCM_RenderProjection, g.perspective ? "PERSPECTIVE" : "ORTHOGRAPHIC", "Render Projection");
  PutDoubles(d, DCM_ViewpointPosition, g.viewpoint.data(), 3, "Viewpoint Position");
  PutDoubles(d, DCM_ViewpointLookAtPoint, g.look_at.data(), 3, "Viewpoint LookAt Point");
  PutDoubles(d, DCM_ViewpointUpDirection, g.up.data(), 3, "Viewpoint Up Direction");
  PutDoubles(d, DCM_RenderFieldOfView, g.field_of_view.data(), 6, "Render Field of View");
  Put(d, DCM_RenderingMethod, "VOLUME_RENDERED", "Rendering Method");
  PutDoubles(d, DCM_SamplingStepSize, &s.classification.sampling_step_mm, 1, "Sampling Step Size");
  // Render Shading: a Phong stand-in for the path tracer's lights and materials, for viewers that implement it.
  const Shading& shading = s.shading;
  Put(d, DCM_ShadingStyle, "DOUBLESIDED", "Shading Style");
  PutDoubles(d, DCM_AmbientReflectionIntensity, &shading.ambient, 1, "Ambient Reflection Intensity");
  PutDoubles(d, DCM_LightDirection, shading.light_direction.data(), 3, "Light Direction");
  PutDoubles(d, DCM_DiffuseReflectionIntensity, &shading.diffuse, 1, "Diffuse Reflection Intensity");
  PutDoubles(d, DCM_SpecularReflectionIntensity, &shading.specular, 1, "Specular Reflection Intensity");
  PutDoubles(d, DCM_Shininess, &shading.shininess, 1, "Shininess");
}

// One ONE_TO_RGBA component: input `number` through `c`'s palette.
void WriteComponent(DcmItem& stream, std::uint16_t number, const Classification& c) {
  DcmItem& component =
      NewItem(stream, DCM_PresentationStateClassificationComponentSequence, "Classification Component Sequence");
  if (!c.description.empty()) {
    PutText(component, DCM_RGBATransferFunctionDescription, "classification.description", c.description, 64);
  }
  Put(component, DCM_ComponentType, "ONE_TO_RGBA", "Component Type");
  PutShort(NewItem(component, DCM_ComponentInputSequence, "Component Input Sequence"),
           DCM_VolumetricPresentationInputIndex, number, "Input Index");
  Put(component, DCM_RGBLUTTransferFunction, "TABLE", "RGB LUT Transfer Function");
  Put(component, DCM_AlphaLUTTransferFunction, "TABLE", "Alpha LUT Transfer Function");
  const std::uint16_t descriptor[3] = {std::uint16_t(kPaletteEntries), 0, 16};
  const DcmTagKey descriptors[4] = {DCM_RedPaletteColorLookupTableDescriptor,
                                    DCM_GreenPaletteColorLookupTableDescriptor,
                                    DCM_BluePaletteColorLookupTableDescriptor,
                                    DCM_AlphaPaletteColorLookupTableDescriptor};
  const DcmTagKey data[4] = {DCM_RedPaletteColorLookupTableData, DCM_GreenPaletteColorLookupTableData,
                             DCM_BluePaletteColorLookupTableData, DCM_AlphaPaletteColorLookupTableData};
  std::vector<Uint16> channel(c.rgba.size());
  for (int k = 0; k < 4; ++k) {
    // Red, green and blue descriptors are "US or SS": US, as their first mapped value is 0.
    Require(component.putAndInsertUint16Array(DcmTag(descriptors[k], EVR_US), descriptor, 3), kDocument,
            "a palette descriptor");
    for (std::size_t i = 0; i < channel.size(); ++i) channel[i] = c.rgba[i][k];
    Require(component.putAndInsertUint16Array(DcmTag(data[k], EVR_OW), channel.data(), unsigned(channel.size())),
            kDocument, "a palette");
  }
}

// One volume stream whose components classify the inputs in order (the Segmented class blends each over the ones
// before it, B over A).
void WriteDisplay(DcmDataset& d, const PresentationState& s, const std::string& input_set_uid) {
  Put(d, DCM_PixelPresentation, "TRUE_COLOR", "Pixel Presentation");
  DcmItem& stream = NewItem(d, DCM_VolumeStreamSequence, "Volume Stream Sequence");
  Put(stream, DCM_VolumetricPresentationInputSetUID, input_set_uid, "Input Set UID");
  const std::vector<Input> inputs = Inputs(s, 1);
  for (std::size_t i = 0; i < inputs.size(); ++i) WriteComponent(stream, std::uint16_t(i + 1), *inputs[i].palette);
  PutEmptySequence(d, DCM_PresentationStateCompositorComponentSequence, "Compositor Component Sequence");
  const std::vector<Uint8> icc = SrgbIccProfile();
  Require(d.putAndInsertUint8Array(DCM_ICCProfile, icc.data(), unsigned(icc.size())), kDocument, "ICC Profile");
  Put(d, DCM_ColorSpace, "SRGB", "Color Space");
}

// Common Instance Reference: every instance referenced above, by series.
void WriteReferences(DcmDataset& d, const std::string& source_series, const ReportSource& source,
                     const PresentationState& s) {
  DcmItem& series = NewItem(d, DCM_ReferencedSeriesSequence, "Referenced Series Sequence");
  Put(series, DCM_SeriesInstanceUID, source_series, "Series Instance UID");
  for (const ReportImage& image : source.images) {
    PutReference(NewItem(series, DCM_ReferencedInstanceSequence, "Referenced Instance Sequence"),
                 image.sop_class_uid, image.sop_instance_uid);
  }
  if (s.segmentation) {
    DcmItem& seg = NewItem(d, DCM_ReferencedSeriesSequence, "Referenced Series Sequence");
    Put(seg, DCM_SeriesInstanceUID, s.segmentation->series_uid, "Series Instance UID");
    PutReference(NewItem(seg, DCM_ReferencedInstanceSequence, "Referenced Instance Sequence"), kSegmentationSopClass,
                 s.segmentation->sop_instance_uid);
  }
  if (!s.rendered_sop_instance_uid.empty()) {
    DcmItem& rendered = NewItem(d, DCM_ReferencedSeriesSequence, "Referenced Series Sequence");
    Put(rendered, DCM_SeriesInstanceUID, s.rendered_series_uid, "Series Instance UID");
    PutReference(NewItem(rendered, DCM_ReferencedInstanceSequence, "Referenced Instance Sequence"),
                 s.rendered_sop_class_uid, s.rendered_sop_instance_uid);
  }
}

}  // namespace

std::string MakePresentationState(const SourceStudy& study, const ReportSource& source,
                                  const PresentationState& state, const std::string& version,
                                  PresentationStateUids* uids_out) {
  QuietDcmtk();
  const std::string study_uid = WithoutTrailingSpaces(study.study_uid);
  const std::string source_series = WithoutTrailingSpaces(study.series_uid);
  if (!IsValidUid(study_uid)) Refuse("source.study_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  if (!IsValidUid(source_series)) Refuse("source.series_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  if (!IsValidUid(source.frame_of_reference_uid)) {
    Refuse("source.frame_of_reference_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  }
  if (source.images.empty()) Refuse("source.images", "is empty: a VOLUME input names its images");
  for (std::size_t i = 0; i < source.images.size(); ++i) {
    if (!IsValidUid(source.images[i].sop_class_uid) || !IsValidUid(source.images[i].sop_instance_uid)) {
      Refuse(fmt::format("source.images[{}]", i), "has a SOP class or instance UID that is not a DICOM UID");
    }
  }
  if (!state.rendered_sop_instance_uid.empty() &&
      (!IsValidUid(state.rendered_sop_class_uid) || !IsValidUid(state.rendered_sop_instance_uid) ||
       !IsValidUid(state.rendered_series_uid))) {
    Refuse("rendered", "has a UID that is not a DICOM UID");
  }
  CheckGeometry(state.geometry);
  CheckCropping(state.cropping);
  CheckClassification(state.classification);
  CheckShading(state.shading);
  if (state.segmentation) CheckSegmentation(*state.segmentation);
  CheckLabel(state.label);
  if (state.recipe_json.size() > kMaxRecipeBytes) Refuse("recipe_json", "is longer than 4 MiB");
  if (version.empty() || version.size() > 64 || !IsAscii(version)) Refuse("version", "is not 1 to 64 ASCII characters");

  DcmFileFormat file;
  DcmDataset& d = *file.getDataset();
  const bool ascii = IsAscii(study.patient_name) && IsAscii(study.patient_id) && IsAscii(study.study_id) &&
                     IsAscii(study.accession_number) && IsAscii(study.referring_physician) &&
                     IsAscii(study.study_description) && IsAscii(state.description) &&
                     IsAscii(state.classification.description);
  if (!ascii) Put(d, DCM_SpecificCharacterSet, "ISO_IR 192", "Specific Character Set");
  const PresentationStateUids uids{study_uid, NewUid(), NewUid()};
  const DicomNow now = CurrentDateTime();
  Put(d, DCM_SOPClassUID,
      state.segmentation ? kSegmentedVolumeRenderingPresentationSopClass : kVolumeRenderingPresentationSopClass,
      "SOP Class UID");
  Put(d, DCM_SOPInstanceUID, uids.sop_instance_uid, "SOP Instance UID");
  Put(d, DCM_InstanceCreationDate, now.date, "Instance Creation Date");
  Put(d, DCM_InstanceCreationTime, now.time, "Instance Creation Time");
  Put(d, DCM_StudyInstanceUID, study_uid, "Study Instance UID");
  PutStudyAttributes(d, study);
  WriteSeriesAndEquipment(d, uids, source.frame_of_reference_uid, version, now);
  WriteIdentification(d, state, now);
  const std::string input_set_uid = NewUid();
  WriteRelationshipAndCropping(d, source, state, input_set_uid);
  WriteViewAndGeometry(d, state);
  WriteDisplay(d, state, input_set_uid);
  WriteReferences(d, source_series, source, state);
  if (!state.recipe_json.empty()) {
    Put(d, kRecipeCreatorTag, kRecipeCreator, "the recipe's private creator");
    DcmTag tag(kRecipeTag);
    tag.setPrivateCreator(kRecipeCreator);  // the dictionary does not know it: the element is made with its VR
    auto recipe = std::make_unique<DcmUnlimitedText>(tag);
    Require(recipe->putOFStringArray(state.recipe_json.c_str()), kDocument, "the recipe");
    Require(d.insert(recipe.release(), true), kDocument, "the recipe");
  }
  const std::string bytes = ToPart10(file, kDocument);
  if (uids_out != nullptr) *uids_out = uids;
  return bytes;
}

namespace {
// ---- Reading ----

namespace tags {
constexpr std::uint32_t kSopClassUid = 0x00080016, kSopInstanceUid = 0x00080018;
constexpr std::uint32_t kReferencedSeries = 0x00081115, kReferencedImage = 0x00081140,
                        kReferencedInstance = 0x0008114A, kReferencedSopClass = 0x00081150,
                        kReferencedSopInstance = 0x00081155, kOtherStudies = 0x00081200;
constexpr std::uint32_t kStudyUid = 0x0020000D, kSeriesUid = 0x0020000E, kFrameOfReference = 0x00200052;
constexpr std::uint32_t kWindowCenter = 0x00281050, kWindowWidth = 0x00281051;
constexpr std::uint32_t kPaletteDescriptor[4] = {0x00281101, 0x00281102, 0x00281103, 0x00281104};
constexpr std::uint32_t kPaletteData[4] = {0x00281201, 0x00281202, 0x00281203, 0x00281204};
constexpr std::uint32_t kRgbTransfer = 0x0028140F, kAlphaTransfer = 0x00281410;
constexpr std::uint32_t kContentLabel = 0x00700080, kContentDescription = 0x00700081;
constexpr std::uint32_t kRenderedImage = 0x00701104, kInputs = 0x00701201, kInputType = 0x00701202, kCrop = 0x00701204,
                        kInputSetUid = 0x00701209, kInputSets = 0x0070120A, kGlobalCrop = 0x0070120B,
                        kGlobalCropIndex = 0x0070120C;
constexpr std::uint32_t kCroppings = 0x00701301, kCroppingMethod = 0x00701302, kBoundingBox = 0x00701303,
                        kObliquePlanes = 0x00701304, kPlane = 0x00701305, kCroppingNumber = 0x00701309;
constexpr std::uint32_t kProjection = 0x00701602, kViewpoint = 0x00701603, kLookAt = 0x00701604, kUp = 0x00701605,
                        kFieldOfView = 0x00701606, kSamplingStep = 0x00701607;
constexpr std::uint32_t kShadingStyle = 0x00701701, kAmbient = 0x00701702, kLightDirection = 0x00701703,
                        kDiffuse = 0x00701704, kSpecular = 0x00701705, kShininess = 0x00701706;
constexpr std::uint32_t kComponents = 0x00701801, kComponentType = 0x00701802, kComponentInputs = 0x00701803,
                        kInputIndex = 0x00701804, kStreams = 0x00701A08, kRgbaDescription = 0x00701A09;
constexpr std::uint32_t kInputNumber = 0x00701207, kCropIndex = 0x00701205, kReferencedSegment = 0x0062000B;
}  // namespace tags

class PresentationReader {
 public:
  explicit PresentationReader(std::string bytes) : d_(Read(std::move(bytes))), root_(d_.root()) {}

  ReadPresentation Run() {
    ReadPresentation out;
    const std::string sop_class = Text(root_, tags::kSopClassUid, "SOP Class UID");
    segmented_ = sop_class == kSegmentedVolumeRenderingPresentationSopClass;
    if (sop_class != kVolumeRenderingPresentationSopClass && !segmented_) {
      const bool several = sop_class == UID_MultipleVolumeRenderingVolumetricPresentationStateStorage;
      throw InputError(fmt::format("not a Volume Rendering Volumetric Presentation State ({}, or its Segmented kind): "
                                   "its SOP class is {}{}",
                                   kVolumeRenderingPresentationSopClass, Clean(sop_class, 64),
                                   several ? ", whose several volume streams cinevol does not read" : ""));
    }
    out.uids = {Uid(root_, tags::kStudyUid, "Study Instance UID"), Uid(root_, tags::kSeriesUid, "Series Instance UID"),
                Uid(root_, tags::kSopInstanceUid, "SOP Instance UID")};
    out.frame_of_reference_uid = Uid(root_, tags::kFrameOfReference, "Frame of Reference UID");
    PresentationState& s = out.state;
    s.label = Clean(Text(root_, tags::kContentLabel, "Content Label"), 16);
    s.description = Clean(d_.Text(root_, tags::kContentDescription).value_or(""), 64);
    const std::string input_set_uid = ReadInputSet();
    FindSource(out);
    out.input_images = images_;
    ReadCroppings(s.cropping);
    ReadGeometry(s);
    ReadInputs(s, input_set_uid);
    ReadRendered(s);
    s.recipe_json = Recipe();
    return out;
  }

 private:
  static Part10Dataset Read(std::string bytes) {
    Part10Limits limits;
    limits.max_bytes = kMaxPresentationBytes;
    return Part10Dataset::Read(std::move(bytes), limits);
  }

  // Text from the file as valid UTF-8 of at most `max_bytes` bytes, for messages and names.
  static std::string Clean(const std::string& raw, std::size_t max_bytes) { return CleanText(raw, max_bytes); }

  [[noreturn]] static void Missing(const char* name, std::uint32_t tag) {
    throw InputError(fmt::format("the presentation state has no {} {}, which it needs", name, TagName(tag)));
  }

  std::string Text(const Part10Item& item, std::uint32_t tag, const char* name) const {
    std::optional<std::string> text = d_.Text(item, tag);
    if (!text || text->empty()) Missing(name, tag);
    return *text;
  }

  std::string Uid(const Part10Item& item, std::uint32_t tag, const char* name) const {
    const std::string uid = Text(item, tag, name);
    if (!IsValidUid(uid)) throw InputError(fmt::format("the presentation state's {} {} is not a UID", name, TagName(tag)));
    return uid;
  }

  // Exactly `count` finite numbers of an FD (or FL) element.
  std::vector<double> Numbers(const Part10Item& item, std::uint32_t tag, std::size_t count, const char* name) const {
    if (d_.Find(item, tag) == nullptr) Missing(name, tag);
    std::vector<double> values = d_.Floats(item, tag, count);
    if (values.size() != count) {
      throw InputError(fmt::format("the presentation state's {} {} holds {} numbers; {} were expected", name,
                                   TagName(tag), values.size(), count));
    }
    for (double v : values) {
      if (!std::isfinite(v) || std::abs(v) > kMaxCoordinate) {
        throw InputError(fmt::format("the presentation state's {} {} holds a number that is not finite or beyond "
                                     "+-1e7",
                                     name, TagName(tag)));
      }
    }
    return values;
  }

  // The values of a US element.
  std::vector<std::uint16_t> Shorts(const Part10Item& item, std::uint32_t tag, const char* name) const {
    const Part10Element* e = d_.Find(item, tag);
    if (e == nullptr) Missing(name, tag);
    if (!e->Is("US") && !e->Is("SS") && !e->Is("OW") && !e->Is("UN")) {
      throw InputError(fmt::format("the presentation state's {} {} has VR {}; US was expected", name, TagName(tag),
                                   e->Vr()));
    }
    if (e->value.size() % 2 != 0) {
      throw InputError(fmt::format("the presentation state's {} {} is not a whole number of 16-bit values", name,
                                   TagName(tag)));
    }
    std::vector<std::uint16_t> values(e->value.size() / 2);
    for (std::size_t i = 0; i < values.size(); ++i) {
      values[i] = std::uint16_t(std::uint8_t(e->value[2 * i]) | std::uint8_t(e->value[2 * i + 1]) << 8);
    }
    return values;
  }

  // The first value of a DS element.
  double Decimal(const Part10Item& item, std::uint32_t tag, const char* name) const {
    std::string text = Text(item, tag, name);
    text = text.substr(0, text.find('\\'));
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0' || !std::isfinite(value)) {
      throw InputError(fmt::format("the presentation state's {} {} is not a decimal number", name, TagName(tag)));
    }
    return value;
  }

  const Part10Item& One(const Part10Item& item, std::uint32_t tag, const char* name, const char* what_more) const {
    const std::vector<const Part10Item*> items = d_.Items(item, tag);
    if (items.size() != 1) {
      throw InputError(fmt::format("the presentation state's {} {} holds {} items; cinevol reads one{}", name,
                                   TagName(tag), items.size(), items.empty() ? "" : what_more));
    }
    return *items.front();
  }

  // The one VOLUME input set; its images go to images_.
  std::string ReadInputSet() {
    const Part10Item& set = One(root_, tags::kInputSets, "Volumetric Presentation Input Set Sequence",
                                " (a presentation of several volumes is not read)");
    if (Text(set, tags::kInputType, "Presentation Input Type") != "VOLUME") {
      throw InputError("the presentation state's input is not a VOLUME");
    }
    for (const Part10Item* image : d_.Items(set, tags::kReferencedImage)) {
      images_.push_back(Uid(*image, tags::kReferencedSopInstance, "Referenced SOP Instance UID"));
    }
    if (images_.empty()) Missing("Referenced Image Sequence of its input", tags::kReferencedImage);
    return Uid(set, tags::kInputSetUid, "Volumetric Presentation Input Set UID");
  }

  // An input's window onto its palette.
  void ReadWindow(const Part10Item& input, Classification& c) const {
    if (d_.Find(input, tags::kWindowCenter) == nullptr) {
      throw InputError("the presentation state's input has no Window Center (0028,1050): cinevol reads a window, "
                       "not a VOI LUT Sequence");
    }
    c.window_center = Decimal(input, tags::kWindowCenter, "Window Center");
    c.window_width = Decimal(input, tags::kWindowWidth, "Window Width");
    if (!(c.window_width > 0)) throw InputError("the presentation state's Window Width (0028,1051) is not positive");
  }

  // The inputs and their classifications: one (Volume Rendering), or the image's and its segments' through a SEG
  // (Segmented Volume Rendering: Segmentation).
  void ReadInputs(PresentationState& s, const std::string& set_uid) {
    const std::vector<const Part10Item*> inputs = d_.Items(root_, tags::kInputs);
    if (inputs.empty() || inputs.size() > kMaxPresentationSegments + 1) {
      throw InputError(fmt::format("the presentation state holds {} inputs; cinevol reads 1 to {}", inputs.size(),
                                   kMaxPresentationSegments + 1));
    }
    if (!segmented_ && inputs.size() != 1) throw InputError("the presentation state holds several inputs");
    const std::map<std::uint16_t, Classification> palettes = ReadPalettes(set_uid);
    Segmentation seg;
    bool base = false;
    for (const Part10Item* input : inputs) {
      if (Uid(*input, tags::kInputSetUid, "Volumetric Presentation Input Set UID") != set_uid) {
        throw InputError("the presentation state's input names an input set it does not hold");
      }
      const std::vector<std::uint16_t> number = Shorts(*input, tags::kInputNumber, "Volumetric Presentation Input Number");
      const auto palette = number.size() == 1 ? palettes.find(number[0]) : palettes.end();
      if (palette == palettes.end()) throw InputError("the presentation state classifies no input it holds");
      Classification c = palette->second;
      ReadWindow(*input, c);
      c.sampling_step_mm = step_;  // one Sampling Step Size for every input
      const SegCrop crop = d_.Text(*input, tags::kCrop).value_or("NO") == "YES" ? SegCropOf(*input) : SegCrop{};
      if (crop.include) {
        if (crop.segments.size() != 1) throw InputError("the presentation state shows several segments as one input");
        seg.shown.push_back({crop.segments.front(), std::move(c)});
      } else {
        if (base) throw InputError("the presentation state classifies the image twice");
        base = true;
        seg.styled = crop.segments;
        s.classification = std::move(c);
      }
      if (!crop.seg_instance.empty()) {
        if (!seg.sop_instance_uid.empty() && seg.sop_instance_uid != crop.seg_instance) {
          throw InputError("the presentation state crops by several SEGs");
        }
        seg.sop_instance_uid = crop.seg_instance;
      }
    }
    if (!segmented_) return;
    if (!base) s.classification = seg.shown.front().palette;  // the image's, as its first segment's
    seg.show_unlisted = base;
    for (const SegmentShown& shown : seg.shown) {
      if (std::find(seg.styled.begin(), seg.styled.end(), shown.number) == seg.styled.end()) {
        seg.styled.push_back(shown.number);
      }
    }
    if (seg.sop_instance_uid.empty()) throw InputError("the Segmented presentation state crops by no SEG");
    seg.series_uid = SeriesOf(seg.sop_instance_uid);
    s.segmentation = std::move(seg);
  }

  // What an input's own cropping says: the SEG and its segments, included or excluded.
  struct SegCrop {
    bool include = false;
    std::vector<std::uint16_t> segments;
    std::string seg_instance;
  };

  SegCrop SegCropOf(const Part10Item& input) const {
    if (!segmented_) {
      throw InputError("the presentation state crops its input by itself (Crop YES), which its class does not allow");
    }
    SegCrop crop;
    for (const std::uint16_t index : Shorts(input, tags::kCropIndex, "Cropping Specification Index")) {
      const auto spec = specifications_.find(index);
      if (spec == specifications_.end()) throw InputError("the presentation state crops by a specification it lacks");
      const std::string method = Text(*spec->second, tags::kCroppingMethod, "Volume Cropping Method");
      if (method != "INCLUDE_SEG" && method != "EXCLUDE_SEG") {
        throw InputError(fmt::format("the presentation state crops an input by {}; cinevol reads INCLUDE_SEG and "
                                     "EXCLUDE_SEG there", Clean(method, 16)));
      }
      crop.include = method == "INCLUDE_SEG";
      const Part10Item& reference = One(*spec->second, tags::kReferencedImage, "Referenced Image Sequence", "");
      crop.seg_instance = Uid(reference, tags::kReferencedSopInstance, "SEG's SOP Instance UID");
      crop.segments = Shorts(reference, tags::kReferencedSegment, "Referenced Segment Number");
    }
    return crop;
  }

  // The series of an instance the Common Instance Reference lists.
  std::string SeriesOf(const std::string& instance_uid) const {
    for (const Part10Item* series : d_.Items(root_, tags::kReferencedSeries)) {
      for (const Part10Item* instance : d_.Items(*series, tags::kReferencedInstance)) {
        if (d_.Text(*instance, tags::kReferencedSopInstance).value_or("") == instance_uid) {
          return Uid(*series, tags::kSeriesUid, "Series Instance UID");
        }
      }
    }
    throw InputError(fmt::format("the presentation state's Common Instance Reference lists no series of {}",
                                 Clean(instance_uid, 64)));
  }

  // The input's series (and study): the Common Instance Reference item that holds its first image.
  void FindSource(ReadPresentation& out) const {
    const auto holds_image = [&](const Part10Item& series) {
      for (const Part10Item* instance : d_.Items(series, tags::kReferencedInstance)) {
        if (d_.Text(*instance, tags::kReferencedSopInstance).value_or("") == images_.front()) return true;
      }
      return false;
    };
    for (const Part10Item* series : d_.Items(root_, tags::kReferencedSeries)) {
      if (holds_image(*series)) {
        out.source_study_uid = out.uids.study_uid;
        out.source_series_uid = Uid(*series, tags::kSeriesUid, "Series Instance UID");
        return;
      }
    }
    for (const Part10Item* study : d_.Items(root_, tags::kOtherStudies)) {
      for (const Part10Item* series : d_.Items(*study, tags::kReferencedSeries)) {
        if (holds_image(*series)) {
          out.source_study_uid = Uid(*study, tags::kStudyUid, "Study Instance UID");
          out.source_series_uid = Uid(*series, tags::kSeriesUid, "Series Instance UID");
          return;
        }
      }
    }
    throw InputError("the presentation state's Common Instance Reference places its input's images in no series");
  }

  // Every cropping specification by its number; the global ones into `c`.
  void ReadCroppings(Cropping& c) {
    for (const Part10Item* spec : d_.Items(root_, tags::kCroppings)) {
      const std::vector<std::uint16_t> number = Shorts(*spec, tags::kCroppingNumber, "Cropping Specification Number");
      if (number.size() == 1) specifications_[number[0]] = spec;
    }
    if (d_.Text(root_, tags::kGlobalCrop).value_or("NO") != "YES") return;
    std::size_t planes = 0;
    for (const std::uint16_t index : Shorts(root_, tags::kGlobalCropIndex, "Global Cropping Specification Index")) {
      const auto found = specifications_.find(index);
      if (found == specifications_.end()) throw InputError("the presentation state crops by a specification it lacks");
      const Part10Item& spec = *found->second;
      const std::string method = Text(spec, tags::kCroppingMethod, "Volume Cropping Method");
      if (method == "BOUNDING_BOX") {
        if (c.bounding_box) throw InputError("the presentation state crops to several bounding boxes");
        const std::vector<double> box = Numbers(spec, tags::kBoundingBox, 6, "Bounding Box Crop");
        c.bounding_box.emplace();
        std::copy(box.begin(), box.end(), c.bounding_box->begin());
      } else if (method == "OBLIQUE_PLANES" || method == "OBLIQUE_PLANE" || method == "OBLIQUE") {
        std::vector<CroppingPlane>& set = c.plane_sets.emplace_back();
        for (const Part10Item* item : d_.Items(spec, tags::kObliquePlanes)) {
          const std::vector<double> abcd = Numbers(*item, tags::kPlane, 4, "Plane");
          const double norm = std::hypot(abcd[0], abcd[1], abcd[2]);
          if (!(norm > 0)) throw InputError("the presentation state crops by a plane with no normal");
          if (++planes > kMaxPresentationPlanes) {
            throw InputError(fmt::format("the presentation state crops by more than {} planes", kMaxPresentationPlanes));
          }
          set.push_back({{abcd[0] / norm, abcd[1] / norm, abcd[2] / norm, abcd[3] / norm}});
        }
        if (set.empty()) Missing("Oblique Cropping Plane Sequence", tags::kObliquePlanes);
      } else {
        throw InputError(fmt::format("the presentation state crops every input by {}, which cinevol does not read "
                                     "(it reads BOUNDING_BOX and OBLIQUE_PLANES there)",
                                     Clean(method, 16)));
      }
    }
  }

  void ReadGeometry(PresentationState& s) {
    RenderGeometry& g = s.geometry;
    const std::string projection = Text(root_, tags::kProjection, "Render Projection");
    if (projection != "PERSPECTIVE" && projection != "ORTHOGRAPHIC") {
      throw InputError(fmt::format("the presentation state's Render Projection is {}", Clean(projection, 16)));
    }
    g.perspective = projection == "PERSPECTIVE";
    const auto vec = [&](std::uint32_t tag, const char* name, Vec3d& out) {
      const std::vector<double> v = Numbers(root_, tag, 3, name);
      std::copy(v.begin(), v.end(), out.begin());
    };
    vec(tags::kViewpoint, "Viewpoint Position", g.viewpoint);
    vec(tags::kLookAt, "Viewpoint LookAt Point", g.look_at);
    vec(tags::kUp, "Viewpoint Up Direction", g.up);
    const std::vector<double> fov = Numbers(root_, tags::kFieldOfView, 6, "Render Field of View");
    std::copy(fov.begin(), fov.end(), g.field_of_view.begin());
    try {
      CheckGeometry(g);
    } catch (const InputError& e) {
      throw InputError(fmt::format("the presentation state's view: {}", e.what()));
    }
    if (d_.Find(root_, tags::kSamplingStep) != nullptr) {
      const double step = Numbers(root_, tags::kSamplingStep, 1, "Sampling Step Size")[0];
      if (!(step > 0)) throw InputError("the presentation state's Sampling Step Size (0070,1607) is not positive");
      step_ = step;
    }
    ReadShading(s.shading);
  }

  // Render Shading where it is there (else an unshaded rendering, A.80.2.4.3: no specular light).
  void ReadShading(Shading& shading) const {
    if (d_.Find(root_, tags::kShadingStyle) == nullptr) {
      shading = {{0, 0, -1}, 1, 0, 0, 0};
      return;
    }
    const auto unit = [&](std::uint32_t tag, const char* name, double absent) {
      if (d_.Find(root_, tag) == nullptr) return absent;
      const double v = Numbers(root_, tag, 1, name)[0];
      if (!(v >= 0 && v <= 1)) throw InputError(fmt::format("the presentation state's {} is outside [0, 1]", name));
      return v;
    };
    shading.ambient = unit(tags::kAmbient, "Ambient Reflection Intensity", 0);
    shading.diffuse = unit(tags::kDiffuse, "Diffuse Reflection Intensity", 0);
    shading.specular = unit(tags::kSpecular, "Specular Reflection Intensity", 0);
    shading.shininess = unit(tags::kShininess, "Shininess", 0.5);
    if (d_.Find(root_, tags::kLightDirection) != nullptr) {
      const std::vector<double> v = Numbers(root_, tags::kLightDirection, 3, "Light Direction");
      const double length = std::hypot(v[0], v[1], v[2]);
      if (!(length > 0)) throw InputError("the presentation state's Light Direction (0070,1703) is no direction");
      shading.light_direction = {v[0] / length, v[1] / length, v[2] / length};
    }
  }

  // One stream; each ONE_TO_RGBA component's palette as 16-bit RGBA, by the input it classifies.
  std::map<std::uint16_t, Classification> ReadPalettes(const std::string& input_set_uid) const {
    const Part10Item& stream = One(root_, tags::kStreams, "Volume Stream Sequence", " (several volumes are not read)");
    if (Uid(stream, tags::kInputSetUid, "Volumetric Presentation Input Set UID") != input_set_uid) {
      throw InputError("the presentation state's volume stream names an input set it does not hold");
    }
    std::map<std::uint16_t, Classification> palettes;
    for (const Part10Item* component : d_.Items(stream, tags::kComponents)) {
      if (Text(*component, tags::kComponentType, "Component Type") != "ONE_TO_RGBA") {
        throw InputError("the presentation state's classification is not ONE_TO_RGBA");
      }
      const Part10Item& input = One(*component, tags::kComponentInputs, "Component Input Sequence", "");
      const std::vector<std::uint16_t> index = Shorts(input, tags::kInputIndex, "Volumetric Presentation Input Index");
      if (index.size() != 1 || palettes.count(index[0]) > 0) {
        throw InputError("the presentation state classifies an input twice, or names none");
      }
      ReadPalette(*component, palettes[index[0]]);
    }
    return palettes;
  }

  void ReadPalette(const Part10Item& component, Classification& c) const {
    c.description = Clean(d_.Text(component, tags::kRgbaDescription).value_or(""), 64);
    const std::string rgb = Text(component, tags::kRgbTransfer, "RGB LUT Transfer Function");
    const std::string alpha = Text(component, tags::kAlphaTransfer, "Alpha LUT Transfer Function");
    if ((rgb != "TABLE" && rgb != "EQUAL_RGB") || (alpha != "TABLE" && alpha != "IDENTITY" && alpha != "NONE")) {
      throw InputError(fmt::format("the presentation state's classification maps RGB by {} and alpha by {}; cinevol "
                                   "reads TABLE or EQUAL_RGB, and TABLE, IDENTITY or NONE",
                                   Clean(rgb, 16), Clean(alpha, 16)));
    }
    std::size_t entries = 0;
    std::vector<std::uint16_t> channels[4];
    for (int k = 0; k < 4; ++k) {
      if ((k < 3 && rgb != "TABLE") || (k == 3 && alpha != "TABLE")) continue;
      const std::vector<std::uint16_t> descriptor = Shorts(component, tags::kPaletteDescriptor[k], "palette descriptor");
      if (descriptor.size() != 3 || descriptor[1] != 0 || descriptor[2] != 16) {
        throw InputError("the presentation state's palette is not one of 16-bit entries from value 0 (cinevol reads "
                         "those)");
      }
      const std::size_t n = descriptor[0] == 0 ? 65536 : descriptor[0];
      if (n < 2 || (entries != 0 && n != entries)) {
        throw InputError("the presentation state's palettes differ in length or hold fewer than 2 entries");
      }
      entries = n;
      channels[k] = Shorts(component, tags::kPaletteData[k], "palette");
      if (channels[k].size() != n) {
        throw InputError(fmt::format("the presentation state's palette holds {} entries; its descriptor says {}",
                                     channels[k].size(), n));
      }
    }
    if (entries == 0) entries = kPaletteEntries;  // neither is a table: a grey ramp and its identity
    c.rgba.resize(entries);
    for (std::size_t i = 0; i < entries; ++i) {
      const auto ramp = std::uint16_t(std::lround(65535.0 * double(i) / double(entries - 1)));
      for (int k = 0; k < 3; ++k) c.rgba[i][k] = rgb == "TABLE" ? channels[k][i] : ramp;
      c.rgba[i][3] = alpha == "TABLE" ? channels[3][i] : alpha == "IDENTITY" ? ramp : std::uint16_t(65535);
    }
  }

  void ReadRendered(PresentationState& s) const {
    const std::vector<const Part10Item*> rendered = d_.Items(root_, tags::kRenderedImage);
    if (rendered.empty()) return;
    s.rendered_sop_class_uid = Uid(*rendered.front(), tags::kReferencedSopClass, "rendered image's SOP class");
    s.rendered_sop_instance_uid = Uid(*rendered.front(), tags::kReferencedSopInstance, "rendered image's UID");
    for (const Part10Item* series : d_.Items(root_, tags::kReferencedSeries)) {
      for (const Part10Item* instance : d_.Items(*series, tags::kReferencedInstance)) {
        if (d_.Text(*instance, tags::kReferencedSopInstance).value_or("") == s.rendered_sop_instance_uid) {
          s.rendered_series_uid = Uid(*series, tags::kSeriesUid, "Series Instance UID");
        }
      }
    }
  }

  // cinevol's recipe, in whichever private block of kRecipeGroup its creator reserved (PS3.5 7.8.1); empty where
  // there is none.
  std::string Recipe() const {
    for (std::uint32_t block = 0x10; block <= 0xff; ++block) {
      const Part10Element* creator = d_.Find(root_, std::uint32_t{kRecipeGroup} << 16 | block);
      if (creator == nullptr || Trimmed(creator->value) != kRecipeCreator) continue;
      const Part10Element* recipe = d_.Find(root_, std::uint32_t{kRecipeGroup} << 16 | block << 8 | kRecipeElement);
      if (recipe == nullptr) return {};
      if (recipe->value.size() > kMaxRecipeBytes) throw InputError("the presentation state's recipe is longer than 4 MiB");
      return std::string(Trimmed(recipe->value));
    }
    return {};
  }

  static std::string_view Trimmed(std::string_view text) {
    while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.remove_suffix(1);
    return text;
  }

  Part10Dataset d_;
  const Part10Item& root_;
  std::vector<std::string> images_;
  bool segmented_ = false;  // the Segmented Volume Rendering class
  double step_ = 1;         // Sampling Step Size (0070,1607): what every palette's alphas are opacities of
  std::map<std::uint16_t, const Part10Item*> specifications_;  // Volume Cropping items by their number
};

}  // namespace

ReadPresentation ReadPresentationState(std::string part10_bytes) {
  return PresentationReader(std::move(part10_bytes)).Run();
}

}  // namespace cinevol::pacs

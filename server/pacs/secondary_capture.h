// Renders sent back to the PACS (issue 34, "Sending back"): a snapshot as a DICOM Secondary Capture filed in its
// source's study, carrying the recipe that renders it again.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cinevol::pacs {

// Secondary Capture Image Storage (PS3.4 B.5).
inline constexpr const char* kSecondaryCaptureSopClass = "1.2.840.10008.5.1.4.1.1.7";
// The private block that holds the recipe: creator (0041,0010) "CINEVOL RECIPE", the recipe JSON in (0041,1001), UT.
inline constexpr std::uint16_t kRecipeGroup = 0x0041;
inline constexpr std::uint8_t kRecipeElement = 0x01;
inline constexpr const char* kRecipeCreator = "CINEVOL RECIPE";
// The series number a render gets: past the acquired series, so viewers that sort by number list renders last.
inline constexpr int kRenderSeriesNumber = 9900;
inline constexpr int kMaxCaptureSide = 16384;  // pixels, each of width and height
inline constexpr std::size_t kMaxSceneJsonBytes = std::size_t{4} << 20;

// The identifying attributes a render copies from its source series, so the picture files under the same patient
// and study in the PACS. Values as the PACS gave them (trailing spaces are dropped); one longer than its VR allows,
// or with characters its VR forbids, is refused, never cut: a changed copy would no longer match the study.
struct SourceStudy {
  std::string patient_name;         // PN: up to 3 groups of 64 characters, "FAMILY^GIVEN"
  std::string patient_id;           // LO: 64 characters
  std::string patient_birth_date;   // DA: YYYYMMDD or empty
  std::string patient_sex;          // CS: "M", "F", "O" or empty
  std::string study_uid;            // UI: required
  std::string study_id;             // SH: 16 characters
  std::string study_date;           // DA
  std::string study_time;           // TM: HHMMSS.FFFFFF, 16 characters
  std::string accession_number;     // SH
  std::string referring_physician;  // PN
  std::string study_description;    // LO
  std::string series_uid;           // UI: the source series, for the recipe
};

struct SecondaryCaptureImage {
  int width = 0;                  // [1; kMaxCaptureSide] pixels
  int height = 0;                 // [1; kMaxCaptureSide] pixels
  std::vector<std::uint8_t> rgb;  // 8-bit RGB, interleaved, rows top first: width * height * 3 bytes
};

struct RenderRecipe {
  std::string scene_json;         // the scene as proto3 JSON: one object, at most kMaxSceneJsonBytes
  std::string source_series_uid;  // empty: SourceStudy::series_uid; else it must equal that where both are set
  std::string cinevol_version;    // 1 to 64 of A-Z a-z 0-9 . + - _
  std::string preset;             // may be empty; the series description names it (cut to fit 64 characters)
};

struct SecondaryCaptureUids {
  std::string study_uid;         // copied from the source
  std::string series_uid;        // new per capture
  std::string sop_instance_uid;  // new per capture
};

// A DICOM Part 10 Secondary Capture Image, explicit VR little endian, uncompressed RGB: patient and study attributes
// copied from `source`, a new series and SOP instance UID (NewUid), Modality OT, Conversion Type WSD, Series
// Description "cinevol render: <preset>" (or "cinevol render"), content date and time now, Burned In Annotation NO.
// The recipe {"scene": <scene object>, "sourceSeriesUid": ..., "cinevolVersion": ..., "preset": ...} goes into the
// private block above; Image Comments and Derivation Description say, for a person, where it is. Throws
// InputError naming the field for a bad input. Its UIDs go to `uids_out` where given.
std::string MakeSecondaryCapture(const SourceStudy& source, const SecondaryCaptureImage& image,
                                 const RenderRecipe& recipe, SecondaryCaptureUids* uids_out = nullptr);

// What ReadSecondaryCapture finds in a capture that MakeSecondaryCapture wrote.
struct ReadCapture {
  std::string recipe_json;  // byte for byte as written
  std::string scene_json;   // the recipe's scene, written again by protobuf: the same JSON value, maybe other spacing
  std::string source_series_uid;
  std::string cinevol_version;
  std::string preset;
  SecondaryCaptureUids uids;
  std::string patient_id;
  std::string patient_name;
  int width = 0;
  int height = 0;
};

// Reads back what MakeSecondaryCapture wrote (for tests, and for `cinevol` to render a picture again): a Part 10
// file in explicit VR little endian, walked up to the pixels without GDCM (whose assertions abort the process on
// some malformed files). Throws InputError ("not a cinevol render: ...") for anything else: not Part 10, another
// transfer syntax or SOP class, truncated, no recipe block, or a recipe not of the shape above.
ReadCapture ReadSecondaryCapture(const std::string& part10_bytes);

// A new UID under the 2.25 root (PS3.5 B.2, ITU-T X.667): "2.25." and a random (version 4) UUID as a decimal
// number, unique without a registered root and at most 44 characters.
std::string NewUid();

}  // namespace cinevol::pacs

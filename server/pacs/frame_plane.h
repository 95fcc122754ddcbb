// Where a frame of a DICOM image lies in the patient, from the instance's
// WADO-RS metadata (DICOM JSON): what a rendered frame (PS3.18 Supplement
// 174, PacsService.RenderFrame) samples from the series' volume.
#pragma once

#include <array>
#include <atomic>
#include <string>

#include "pacs/dicom_json.h"
#include "pacs/dicomweb_client.h"

namespace cinevol::pacs {

using Triple = std::array<double, 3>;

struct FramePlane {
  Triple position;  // Image Position (Patient): the top-left pixel's centre, LPS mm
  Triple row;       // Image Orientation (Patient), unit: along a row (to the next column)
  Triple column;    // unit, perpendicular to `row`: down a column (to the next row)
  int rows = 0, columns = 0;
  double row_spacing_mm = 0;     // Pixel Spacing's first value: between rows
  double column_spacing_mm = 0;  // its second: between columns
};

// The plane of frame `frame` (from 1; 0: the instance's only frame) of `instance`: Image Position and
// Orientation and Pixel Spacing at the top level (single-frame images), or in
// the per-frame and shared functional groups (enhanced multi-frame ones, the
// per-frame ones first). Throws InputError naming what is missing or absurd
// (a position past 1e9 mm, a spacing outside [1e-4, 1e4] mm, orientation
// vectors that are not two directions across each other, frame 0 of an
// instance of several), and PacsError 404 for a frame past its Number of
// Frames.
FramePlane FramePlaneOf(const DicomJsonDataset& instance, int frame);

// WADO-RS /studies/{study}/series/{series}/instances/{instance}/metadata, then
// FramePlaneOf. PacsError for a failing PACS or an instance it does not hold.
FramePlane FetchFramePlane(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                           const std::string& instance_uid, int frame, const std::atomic<bool>* cancel = nullptr);

}  // namespace cinevol::pacs

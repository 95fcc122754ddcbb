// Inside the reader cage: DICOM series from a folder's files. GDCM scans the
// headers (after checks.h's walk); cinevol groups the files into series,
// sorts one series' slices along their normal and checks them: gantry tilt
// measured, uneven gaps, duplicates and colour refused. A series whose
// positions each hold the same number of files is a time series (cardiac
// phases, a dynamic series): its phases ordered in time at each position.
// The ITK/GDCM adapter (readers/itk_adapter.h) decodes the pixels.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cinevol/reader/reader.pb.h"
#include "io/readers/volume_read.h"

namespace cinevol::formats::dicom {

// Slice stacks sheared by more than this (degrees) count as gantry tilt, and
// are resampled.
inline constexpr double kMaxTiltDeg = 0.1;

struct Slice {
  std::string file;
  double position[3];
  double along_normal;
};

// The checked, sorted geometry of one series (of its first phase, which every
// phase shares).
struct SeriesGeometry {
  std::vector<Slice> slices;
  double row[3], col[3], normal[3];
  double slice_gap_mm = 1.0;
  // Above kMaxTiltDeg: the stack is sheared along its slices (a gantry tilt):
  // each slice is shifted in its own plane onto a regular grid, as Slicer does.
  double tilt_deg = 0;
  // Gaps that differ (ReadOptions::resample_uneven): the slices are resampled
  // along the normal onto an even grid of slice_gap_mm, the smallest gap.
  bool uneven = false;
  double largest_gap_mm = 0;
  std::string largest_gap_between;  // "A and B", the files around it
  // The slices the even grid has: all of them where the gaps are even.
  std::size_t GridSlices() const;
};

// One series chosen, its slices sorted and checked: what the adapter decodes.
struct SortedSeries {
  std::string shown;  // what messages call the folder
  reader::Series info;
  SeriesGeometry geometry;
  std::string modality;               // the first slice's
  bool rescaled_alike = true;         // every slice with the same rescale slope and intercept
  reader::Identity identity;          // the first slice's patient and study fields
  std::vector<double> stored_window;  // the first slice's first window: center, width; or empty
  std::string frame_of_reference_uid;  // the first slice's (0020,0052); empty when it names none
  // A PET (modality PT): what SUVbw needs as the files say it, unchecked (the
  // parent checks it: io/suv.h); nothing for any other modality.
  std::optional<reader::PetDose> pet;
  // Each phase's files in the order of geometry.slices: one phase (the
  // geometry's files) for a still series; for a time series (N > 1 files at
  // every position), phase k holds each position's k-th file in time.
  std::vector<std::vector<std::string>> phases;
  // A time series: what ordered each position's files (phase_order: "Temporal
  // Position Identifier", "Trigger Time" or "Instance Number") and each
  // phase's time in seconds, the mean of its files' Trigger Times (empty
  // where a file has none, or where the means do not rise phase by phase).
  std::string phase_order;
  std::vector<double> phase_seconds;
};

// The series `files` hold, largest first. Files whose structure is not sound
// DICOM (with the pre-checks on) and files GDCM cannot parse are left out.
reader::SeriesList ListSeries(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options);

// The series of `files` with `series_uid`, or the largest, sorted and checked;
// several files at one position are read as phases where every position holds
// as many, each ordered by Temporal Position Identifier (0020,0100), else
// Trigger Time (0018,1060), else Instance Number (0020,0013); refused where
// the counts differ, two of a position share that key, or there are more
// phases than kMaxPhases.
SortedSeries ChooseSeries(const std::vector<reader::DicomFile>& files, const std::string& series_uid,
                          const reader::ReadOptions& options);

// "UID 'description' (modality, size pixels, n files)", for messages.
std::string Describe(const reader::Series& s);

double Dot3(const double* a, const double* b);

}  // namespace cinevol::formats::dicom

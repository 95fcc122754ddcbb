// Inside the reader cage: DICOM series from a folder's files. GDCM scans the
// headers (after checks.h's walk); cinevol groups the files into series,
// sorts one series' slices along their normal and checks them: gantry tilt
// measured, uneven gaps, duplicates and colour refused. A slice is a file's
// one image, or a frame of an enhanced multi-frame file (frames.h). A series
// whose positions each hold the same number of slices is a time series
// (cardiac phases, a dynamic series): its phases ordered in time at each
// position. The ITK/GDCM adapter (readers/itk_adapter.h) decodes the pixels.
#pragma once

#include <array>
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
  int frame = -1;  // the frame of an enhanced multi-frame file, from 0; -1: the file's one image
  double position[3] = {0, 0, 0};
  double along_normal = 0;
  // What orders it in time where a position holds several (see ChooseSeries):
  // a file's Temporal Position Identifier, Trigger Time (ms) and Instance
  // Number; a frame's Temporal Position Index, Nominal Cardiac Trigger Delay
  // Time (ms) and number in its file. Unset where the slice has none.
  std::array<std::optional<double>, 3> time_keys;
  // A frame's own rescale (its Pixel Value Transformation); a file's is GDCM's.
  double rescale_slope = 1, rescale_intercept = 0;
};

// The checked, sorted geometry of one series (of its first phase, which every
// phase shares).
struct SeriesGeometry {
  std::vector<Slice> slices;
  double row[3], col[3], normal[3];
  double slice_gap_mm = 1.0;
  // An enhanced multi-frame file's pixel spacing {x, y} from its functional
  // groups; {0, 0}: GDCM's reading of the first file.
  std::array<double, 2> pixel_spacing_mm{0, 0};
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
  bool multi_frame = false;           // one enhanced multi-frame file, its frames the slices
  std::string frame_of_reference_uid;  // the first slice's (0020,0052); empty when it names none
  // A PET (modality PT): what SUVbw needs as the files say it, unchecked (the
  // parent checks it: io/suv.h); nothing for any other modality.
  std::optional<reader::PetDose> pet;
  // Each phase's slices in the order of geometry.slices: one phase (the
  // geometry's slices) for a still series; for a time series (N > 1 slices at
  // every position), phase k holds each position's k-th slice in time.
  std::vector<std::vector<Slice>> phases;
  // A time series: what ordered each position's slices (phase_order: the
  // name of the first of Slice::time_keys every slice has) and each phase's
  // time in seconds, the mean of its slices' trigger times (empty where a
  // slice has none, or where the means do not rise phase by phase).
  std::string phase_order;
  std::vector<double> phase_seconds;
};

// The series `files` hold, largest first. Files whose structure is not sound
// DICOM (with the pre-checks on) and files GDCM cannot parse are left out.
reader::SeriesList ListSeries(const std::vector<reader::DicomFile>& files, const reader::ReadOptions& options);

// The series of `files` with `series_uid`, or the largest, sorted and checked;
// several slices at one position are read as phases where every position
// holds as many, each ordered by the first of its time keys every slice has:
// for files Temporal Position Identifier (0020,0100), else Trigger Time
// (0018,1060), else Instance Number (0020,0013); for the frames of an
// enhanced multi-frame file Temporal Position Index (0020,9128), else Nominal
// Cardiac Trigger Delay Time (0020,9153), else their order in the file.
// Refused where the counts differ, two of a position share that key, there
// are more phases than kMaxPhases, or a series holds several multi-frame files.
SortedSeries ChooseSeries(const std::vector<reader::DicomFile>& files, const std::string& series_uid,
                          const reader::ReadOptions& options);

// "UID 'description' (modality, size pixels, n files)", for messages.
std::string Describe(const reader::Series& s);

double Dot3(const double* a, const double* b);

// A backslash-separated decimal string's numbers ("1\0\0"); empty where any
// item is not a finite number.
std::vector<double> Numbers(const std::string& s);

// A DICOM string value: trailing spaces and NULs dropped.
std::string Trimmed(const char* bytes, std::size_t length);

}  // namespace cinevol::formats::dicom

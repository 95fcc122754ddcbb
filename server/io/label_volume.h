// Loads segmentations: a label volume (NIfTI or NRRD, integer labels) fitted
// to its image's grid, and a label table naming the labels. Every failure
// throws InputError naming the file (and the line, for tables).
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <string_view>

#include "cinevol/v1/service.pb.h"
#include "core/labels.h"
#include "core/volume.h"
#include "io/table_finder.h"
#include "io/volume_loader.h"

namespace cinevol {

// The most bytes a label table may have: 117 TotalSegmentator labels take 2 KiB.
inline constexpr std::size_t kMaxLabelTableBytes = std::size_t{1} << 20;

// `value<TAB>name` lines: value an integer in [0, 65535], each once, name not
// empty. Blank lines and lines starting with '#' are skipped. `shown` names
// the table in messages.
std::map<int, std::string> ParseLabelTable(std::string_view text, const std::string& shown);

// Reads a label table file (at most kMaxLabelTableBytes).
std::map<int, std::string> LoadLabelTable(const std::filesystem::path& path, const std::string& shown);

// Fits a label volume (already loaded; every value must be an integer in
// [0, 65535]) to `image`'s grid: taken as it is when dimensions, spacing,
// origin and direction agree; else resampled nearest-neighbour, with labels
// outside its own grid 0, and said so in LabelVolume::note and the log.
// Refused when the grids do not overlap.
LabelVolume FitLabels(const Volume& labels, const Volume& image, const std::string& shown);

// Gives every unlabelled voxel touching labels (its 26 neighbours) a value
// of its own per set of labels touched, above every label (DerivedLabel): the
// partial-volume shell that hides with the labels it touches. FitLabels calls it.
void AddShells(LabelVolume& labels);

// Marks `table` (FindTable's, on the labels' grid) with a value of its own,
// where the segmentation leaves voxels unlabelled; keeps its note.
void AddTable(LabelVolume& labels, const TableMask& table);
// Labels that only mark the table, for a volume without a segmentation.
LabelVolume TableLabels(const TableMask& table);
// Marks `from`'s table on `to` (a segmentation of the same volume loaded later).
void CopyTable(const LabelVolume& from, LabelVolume& to);

// A segmentation of an image whose orientation was given at load (an
// override) takes the same: it was stored as the image was.
void FollowImageOrientation(Volume& labels, const Volume& image);

// LoadVolumeFile under `policy`, FollowImageOrientation, then FitLabels; a
// DICOM SEG (a .dcm file, a DICOM file, a folder) through LoadSegmentation.
LabelVolume LoadLabelVolume(const std::filesystem::path& path, const Volume& image, const LoadPolicy& policy = {});

// What the API and `cinevol info` say of a segmentation: every label present
// and every label the table names.
v1::LabelSet ToLabelSet(const LabelVolume& labels);

// The scene's segmentation (VolumeSource.labels and label_table, relative
// paths against `base_dir`) fitted to `image`; null when it names none.
std::shared_ptr<const LabelVolume> LoadSceneLabels(const v1::VolumeSource& source, const Volume& image,
                                                   const std::filesystem::path& base_dir = {});
// The same, with the table marked where the scene removes it (labels.remove_table):
// what offline renders of a scene file draw. Null when there is neither.
std::shared_ptr<const LabelVolume> LoadSceneLabels(const v1::Scene& scene, const Volume& image,
                                                   const std::filesystem::path& base_dir = {});

}  // namespace cinevol

// The reader cage: every parse of bytes from outside (volume files, DICOM
// series, segmentations, label tables, environment maps) runs in a child
// process, cinevol-reader, so that a reader's crash, hang or appetite is the
// load's error and never the caller's.
//
// The child gets the bytes as file descriptors the parent opened (never a
// path it could swap), runs with no network, no writes, no new processes
// (a seccomp filter) and limits on address space, CPU time and core dumps,
// and hands back a header first. The parent checks the header's size against
// its limits and reserves the memory (LoadPolicy::reserve) before it lets
// the child read the voxels into shared memory (a sealed memfd), in their
// native type. A child that crashes, exceeds a limit, takes too long or
// writes garbage is killed; the load fails with a message that names the
// input and what happened ("upload:head.nrrd: the NRRD reader stopped
// (SIGABRT)"). docs/security.md tells the whole story.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core/image.h"
#include "core/volume.h"
#include "io/formats/format.h"
#include "io/volume_loader.h"

namespace cinevol::reader_cage {

// A file the child reads: where it is, and what the request calls it (a DICOM
// file's path under its folder; a named file as its header names it).
struct Input {
  std::filesystem::path path;
  std::string name;
};

// A volume file, `refs` the files its header names (already checked against
// the policy by the caller): a volume, or a time series (a 4-D file).
VolumeSeries ReadVolumeFile(const std::filesystem::path& file, const formats::References& refs,
                            const LoadPolicy& policy);

// A DICOM series from `files` (a folder's files); the largest when
// `series_uid` is empty.
VolumeSeries ReadDicomSeries(const std::vector<Input>& files, const std::string& series_uid,
                             const LoadPolicy& policy);

// The series `files` hold, largest first.
std::vector<DicomSeriesInfo> ListDicomSeries(const std::vector<Input>& files, const LoadPolicy& policy);

// A DICOM SEG placed onto a volume's grid (io/dicom_seg.h makes it labels).
struct SegmentationRead {
  struct Segment {
    int number = 0;       // the label value
    std::string label;    // Segment Label, valid UTF-8
    bool has_cielab = false;
    std::array<std::uint16_t, 3> cielab{};  // Recommended Display CIELab Value, DICOM's scaled PCS
  };
  std::vector<std::uint16_t> labels;  // one per voxel of the volume, x fastest: a segment number or 0
  std::vector<Segment> segments;      // ascending numbers
  std::string type;                   // "BINARY" or "FRACTIONAL"
  std::string frame_of_reference_uid;
  std::uint32_t frames = 0, frames_outside = 0;
  std::vector<std::string> notes;     // what placing it found (frames outside, overlaps)
};

// The SEG among `files` (one file, or a folder's: exactly one SEG among
// them) onto `image`'s grid. A SEG in another frame of reference than the
// image's (where the image has one) is refused naming both, before any
// memory is reserved; policy.reserve is asked for twice the labels' bytes
// (the shared memory and the copy).
SegmentationRead ReadSegmentation(const std::vector<Input>& files, const Volume& image, const LoadPolicy& policy);

// A label table file (`value<TAB>name` lines); messages call it `shown`.
std::map<int, std::string> ReadLabelTable(const std::filesystem::path& file, const std::string& shown,
                                          const LoadPolicy& policy);

// The same from a label table's text (an upload's header carries one).
std::map<int, std::string> ReadLabelTableText(const std::string& text, const std::string& shown);

// An OpenEXR image as linear RGB.
ImageRgbF ReadExrImage(const std::filesystem::path& file, const std::string& shown, const LoadPolicy& policy);

// A scene light's environment map (an EXR named by its path): what
// scene/scene_builder.h's EnvironmentMapReader is given. Raising `cancel`
// stops the read (Cancelled).
ImageRgbF ReadEnvironmentMap(const std::string& path, const std::atomic<bool>* cancel = nullptr);

// How loads end, for the metrics: "ok", "refused" (the reader named a problem
// with the input), or how the reader was stopped: "crashed" (a signal),
// "sandbox" (a forbidden system call), "memory", "cpu", "timeout",
// "cancelled", "protocol" (an answer that is not the protocol).
using OutcomeObserver = std::function<void(std::string_view outcome)>;
// Called once per load from then on; set before loads begin.
void ObserveOutcomes(OutcomeObserver observer);

// What messages call the reader a request goes to, by its kind and file
// name alone: "NIfTI", "NRRD", "MetaImage", "VTK", "DICOM", "label table",
// "OpenEXR".
std::string ReaderName(int request_kind, const std::string& file_name);

// Keeps one reader started ahead of need from then on, so that loads do not
// wait for a process to start (tens of milliseconds: ITK's and GDCM's start-
// up): for long-lived processes (the server); a command that reads one file
// gains nothing from it.
void KeepSpareReader();

// Whether this kernel has Landlock, which confines a reader to its inputs
// (without it, seccomp and rlimits alone wall it in).
bool KernelHasLandlock();

// Where cinevol-reader is: $CINEVOL_READER, else beside the running program
// (or one folder up, as for the test binary in build/tests/); throws when
// there is none.
std::filesystem::path ReaderPath();

}  // namespace cinevol::reader_cage

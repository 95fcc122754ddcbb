// Inside the reader cage: an enhanced multi-frame image (Enhanced CT, MR or
// PET: one file, many frames), each frame placed and timed by its functional
// groups (PS3.3 C.7.6.16): the Per-frame Functional Groups Sequence
// (5200,9230), or the Shared one (5200,9229) for what every frame shares.
// series.h sorts the frames as it sorts a folder's single-frame files.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace cinevol::formats::dicom {

struct Frame {
  std::array<double, 3> position;  // Plane Position: Image Position (Patient)
  // Frame Content: Temporal Position Index (0020,9128); Cardiac
  // Synchronization: Nominal Cardiac Trigger Delay Time (0020,9153), ms.
  std::optional<double> temporal_position_index;
  std::optional<double> trigger_delay_ms;
  // Pixel Value Transformation: Rescale Slope and Intercept (identity where
  // the groups give none).
  double rescale_slope = 1, rescale_intercept = 0;
};

struct MultiFrame {
  std::vector<Frame> frames;  // in the file's order
  // Plane Orientation: Image Orientation (Patient), every frame's.
  std::array<double, 6> orientation;
  // Pixel Measures: Pixel Spacing as {between columns (x), between rows
  // (y)}, every frame's; its Slice Thickness (0 where none).
  std::array<double, 2> pixel_spacing_mm;
  double slice_thickness_mm = 0;
  // Frame VOI LUT: the first frame's first window {center, width}, or empty.
  std::vector<double> window;
};

// The frames of `file` (named `name` in messages) where it is an enhanced
// multi-frame image: Number of Frames (0028,0008) above 1 and a Per-frame
// Functional Groups Sequence; nothing for any other file. GDCM reads the
// header only, up to the pixels. Throws InputError, naming the frame and
// the attribute, where a frame has no usable position, orientation or pixel
// spacing, where frames differ in orientation or pixel spacing, or where the
// sequence does not hold one item a frame.
std::optional<MultiFrame> ReadMultiFrame(const std::string& file, const std::string& name);

}  // namespace cinevol::formats::dicom

// FramePlaneOf and FetchFramePlane: see frame_plane.h.
#include "pacs/frame_plane.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/error.h"
#include "pacs/dicomweb_requests.h"  // the tags
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

namespace tags {
constexpr std::uint32_t kImagePosition = 0x00200032;
constexpr std::uint32_t kImageOrientation = 0x00200037;
constexpr std::uint32_t kPixelSpacing = 0x00280030;
constexpr std::uint32_t kSharedGroups = 0x52009229;
constexpr std::uint32_t kPerFrameGroups = 0x52009230;
constexpr std::uint32_t kPlanePosition = 0x00209113;
constexpr std::uint32_t kPlaneOrientation = 0x00209116;
constexpr std::uint32_t kPixelMeasures = 0x00289110;
}  // namespace tags

constexpr double kMaxPositionMm = 1e9;  // as slices take them (reading/slice.h kMaxPlaneMm)

// Where one frame's attributes are: its own functional group, the shared
// one, the top level; the first that holds an attribute says it.
struct FrameSources {
  std::vector<DicomJsonDataset> places;

  // The first `count` numbers of `tag` inside macro `sequence` (or at the top level for 0).
  std::optional<std::vector<double>> Find(std::uint32_t sequence, std::uint32_t tag, std::size_t count) const {
    for (const DicomJsonDataset& place : places) {
      const std::vector<DicomJsonDataset> macro = place.Items(sequence, 1);
      std::vector<double> numbers = macro.empty() ? std::vector<double>{} : macro.front().Numbers(tag, count);
      if (numbers.size() == count) return numbers;
    }
    return std::nullopt;
  }
};

double Dot(const Triple& a, const Triple& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Triple Unit(const std::vector<double>& v, std::size_t from) {
  const Triple t{v[from], v[from + 1], v[from + 2]};
  const double length = std::sqrt(Dot(t, t));
  if (!(length > 1e-6) || !std::isfinite(length)) return {0, 0, 0};
  return {t[0] / length, t[1] / length, t[2] / length};
}

int SideOf(const DicomJsonDataset& instance, std::uint32_t tag, const char* name) {
  const std::optional<std::int64_t> side = instance.Count(tag);
  if (!side || *side < 1 || *side > 65535) {
    throw InputError(fmt::format("the instance's {} is {}: a frame needs 1 to 65535", name,
                                 side ? std::to_string(*side) : "missing"));
  }
  return int(*side);
}

}  // namespace

FramePlane FramePlaneOf(const DicomJsonDataset& instance, int frame) {
  const std::int64_t frames = instance.Count(tag::kNumberOfFrames).value_or(1);
  if (frame == 0 && frames > 1) {
    throw InputError(
        fmt::format("the instance has {} frames: ask for one by its number (a rendered instance of "
                    "several frames would need a multi-frame media type, which cinevol does not offer)",
                    frames));
  }
  frame = std::max(frame, 1);
  if (frame > frames) {
    throw PacsError(
        fmt::format("the instance has {} frame{}; frame {} is not one of them", frames, frames == 1 ? "" : "s", frame),
        404);
  }
  FrameSources sources;
  const std::vector<DicomJsonDataset> per_frame = instance.Items(tags::kPerFrameGroups, std::size_t(frame));
  if (per_frame.size() == std::size_t(frame)) sources.places.push_back(per_frame.back());
  for (const DicomJsonDataset& shared : instance.Items(tags::kSharedGroups, 1)) sources.places.push_back(shared);
  // An attribute in a functional group's macro, else at the top level (a single-frame image's place).
  const auto find = [&](std::uint32_t macro, std::uint32_t tag, std::size_t count) {
    std::optional<std::vector<double>> numbers = sources.Find(macro, tag, count);
    if (!numbers && instance.Numbers(tag, count).size() == count) numbers = instance.Numbers(tag, count);
    return numbers;
  };
  const auto position = find(tags::kPlanePosition, tags::kImagePosition, 3);
  const auto orientation = find(tags::kPlaneOrientation, tags::kImageOrientation, 6);
  const auto spacing = find(tags::kPixelMeasures, tags::kPixelSpacing, 2);
  if (!position || !orientation || !spacing) {
    throw InputError(fmt::format("frame {}: the instance's metadata does not place it: {} missing", frame,
                                 !position      ? "Image Position (Patient)"
                                 : !orientation ? "Image Orientation (Patient)"
                                                : "Pixel Spacing"));
  }
  FramePlane plane;
  for (int a = 0; a < 3; ++a) {
    if (!(std::abs((*position)[a]) <= kMaxPositionMm)) {
      throw InputError(fmt::format("frame {}: Image Position (Patient) is not within {:g} mm", frame, kMaxPositionMm));
    }
    plane.position[a] = (*position)[a];
  }
  plane.row = Unit(*orientation, 0);
  plane.column = Unit(*orientation, 3);
  if (Dot(plane.row, plane.row) == 0 || Dot(plane.column, plane.column) == 0 ||
      std::abs(Dot(plane.row, plane.column)) > 0.01) {
    throw InputError(fmt::format("frame {}: Image Orientation (Patient) is not two perpendicular directions", frame));
  }
  plane.row_spacing_mm = (*spacing)[0];
  plane.column_spacing_mm = (*spacing)[1];
  for (double mm : {plane.row_spacing_mm, plane.column_spacing_mm}) {
    if (!(mm >= 1e-4 && mm <= 1e4)) {
      throw InputError(fmt::format("frame {}: Pixel Spacing {:g} mm is outside [1e-4, 1e4]", frame, mm));
    }
  }
  plane.rows = SideOf(instance, tag::kRows, "Rows");
  plane.columns = SideOf(instance, tag::kColumns, "Columns");
  return plane;
}

}  // namespace cinevol::pacs

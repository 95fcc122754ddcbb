// Orientation letters for reading: which way a direction in patient space
// (LPS: +x the patient's left, +y posterior, +z superior) points, as the
// letters radiologists read at a slice's edges (A/P, L/R, S/I).
#pragma once

#include <array>
#include <string>

#include "core/vec.h"

namespace cinevol {

// A second letter is added where the direction's second-largest component
// is at least this (about 14 degrees off the dominant axis in its plane):
// below it a slice reads as straight; "oblique" letters would be noise.
inline constexpr float kSecondLetterMinComponent = 0.25f;

// The letter of the direction's dominant axis, then, for an oblique
// direction, the next one: "L", "A", "LA" (mostly left, partly anterior).
// `lps` need not be normalised; the zero vector gives "".
std::string OrientationLetters(Vec3f lps);

// The LPS direction of index axis `axis` (0 x, 1 y, 2 z) of a volume with
// direction cosines `direction` (VolumeMetadata::direction).
Vec3f IndexAxisDirection(const std::array<double, 9>& direction, int axis);

// The letters at an image's four edges, from its row direction (left to
// right along a row) and column direction (top to bottom down a column).
struct EdgeLetters {
  std::string left, right, top, bottom;
};
EdgeLetters EdgeLettersOf(Vec3f row_direction, Vec3f column_direction);

}  // namespace cinevol

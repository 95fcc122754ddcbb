// Orientation letters from LPS directions.
#include "reading/orientation.h"

#include <cmath>

namespace cinevol {
namespace {

// The letter of axis `axis` (0 x, 1 y, 2 z) in the direction of `sign`.
char AxisLetter(int axis, float sign) { return sign > 0 ? "LPS"[axis] : "RAI"[axis]; }

}  // namespace

std::string OrientationLetters(Vec3f lps) {
  const float length = Length(lps);
  if (!(length > 0.0f)) return "";
  const Vec3f unit = lps / length;
  const Vec3f size = Abs(unit);
  int first = 0;
  for (int a = 1; a < 3; ++a) first = size[a] > size[first] ? a : first;
  int second = first == 0 ? 1 : 0;
  for (int a = 0; a < 3; ++a) second = a != first && size[a] > size[second] ? a : second;
  std::string letters(1, AxisLetter(first, unit[first]));
  if (size[second] >= kSecondLetterMinComponent) letters += AxisLetter(second, unit[second]);
  return letters;
}

Vec3f IndexAxisDirection(const std::array<double, 9>& direction, int axis) {
  return {float(direction[axis]), float(direction[3 + axis]), float(direction[6 + axis])};
}

EdgeLetters EdgeLettersOf(Vec3f row_direction, Vec3f column_direction) {
  return {OrientationLetters(-row_direction), OrientationLetters(row_direction), OrientationLetters(-column_direction),
          OrientationLetters(column_direction)};
}

}  // namespace cinevol

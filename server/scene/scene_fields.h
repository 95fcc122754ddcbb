// The scene's numbers in one table per message: each field's JSON name, its
// range and unit, its default and the server limit that bounds it further.
// Defaults (ApplyDefaults), validation (ValidateScene, ApplyEvent's checks of
// the parts an event touches) and docs/api.md's field table all read these
// tables; a test holds the docs to them. Rules that tie fields together
// (sorted points, a camera's up against its direction, colour x intensity)
// stay code in scene_file.cpp.
#pragma once

#include <algorithm>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

template <class Message>
struct NumberField {
  std::string_view name;  // the JSON name within Message
  double lo, hi;          // the range, both bounds included unless `open`
  bool open;              // the bounds themselves are refused
  std::string_view unit;
  std::optional<double> fallback;  // the default of an unset optional field
  std::string_view limit;          // the server flag that bounds it further, if any
  double (*get)(const Message&);
  bool (*has)(const Message&);  // null: the field has no presence (0 is its default)
  void (*set)(Message&, double);
};

std::span<const NumberField<v1::Camera>> CameraNumbers();
std::span<const NumberField<v1::RenderSettings>> RenderNumbers();
// Scene.transferFunction's and each label style's own; the defaults of
// densityScale and gradientFactor apply only to a function given by points
// (a preset brings its own).
std::span<const NumberField<v1::TransferFunction>> TransferFunctionNumbers();

// Sets the unset optional fields of `message` that have a default, but for
// those named in `except`.
template <class Message>
void FillDefaults(Message& message, std::span<const NumberField<Message>> fields,
                  std::initializer_list<std::string_view> except = {}) {
  for (const NumberField<Message>& f : fields) {
    if (!f.fallback || !f.has || f.has(message)) continue;
    if (std::find(except.begin(), except.end(), f.name) == except.end()) f.set(message, *f.fallback);
  }
}

// "`prefix``name`: V is outside [LO, HI]" for each field of `message` out of
// its range (NaN and infinities included).
template <class Message>
void CheckRanges(const Message& message, std::span<const NumberField<Message>> fields, const std::string& prefix,
                 std::vector<std::string>& problems);

// docs/api.md's table of every field above: path, default, range, unit, limit.
std::string SceneNumbersMarkdown();

}  // namespace cinevol

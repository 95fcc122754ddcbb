// Scene files: proto3 JSON text through ParseSceneJson (parse, defaults,
// validation) and, when it parses, the round trip through SceneToJson; and
// the same bytes as a label table (ParseLabelTable).
// InputError is the expected refusal; crashes and sanitizer reports are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <string_view>

#include "core/error.h"
#include "io/label_volume.h"
#include "scene/scene_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    (void)cinevol::ParseLabelTable(text, "fuzz.tsv");
  } catch (const cinevol::InputError&) {
  }
  cinevol::v1::Scene scene;
  try {
    scene = cinevol::ParseSceneJson(text, "/nonexistent-base");
  } catch (const std::exception&) {
    return 0;
  }
  // A valid scene stays valid through its own JSON.
  try {
    const cinevol::v1::Scene again = cinevol::ParseSceneJson(cinevol::SceneToJson(scene));
    (void)again;
  } catch (const std::exception&) {
    std::abort();
  }
  return 0;
}

// `cinevol pick (--scene S | --volume PATH [--preset P --width W --height H]) --x PX --y PY
// [--threshold 0.5] [--json]`: what the
// ray through pixel (PX, PY) of the scene's camera meets, offline (no server):
// the patient position (LPS mm), the value there and the label, or no hit.
#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>

#include <chrono>
#include <string>

#include "commands.h"
#include "offline_render.h"
#include "reading/pick.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct PickOptions {
  SceneSource source;
  int x = 0, y = 0;
  float threshold = 0.5f;
  bool json = false;
};

// A float as the shortest decimal that reads back as it: 0.1, not 0.10000000149.
double Decimal(float v) { return std::stod(fmt::format("{}", v)); }

google::protobuf::Value Number(float v) {
  google::protobuf::Value value;
  value.set_number_value(Decimal(v));
  return value;
}

google::protobuf::Value Null() {
  google::protobuf::Value value;
  value.set_null_value(google::protobuf::NULL_VALUE);
  return value;
}

google::protobuf::Value List(std::initializer_list<float> numbers) {
  google::protobuf::Value value;
  for (float n : numbers) *value.mutable_list_value()->add_values() = Number(n);
  return value;
}

// {"hit", "position" (LPS mm), "value", "label" {"value", "name"}, "pixel"}; null where there is no hit.
google::protobuf::Struct PickJson(const PickResult& r, const PickOptions& o) {
  google::protobuf::Struct out;
  auto& fields = *out.mutable_fields();
  fields["hit"].set_bool_value(r.hit);
  fields["pixel"] = List({float(o.x), float(o.y)});
  fields["position"] = r.hit ? List({r.position_lps.x, r.position_lps.y, r.position_lps.z}) : Null();
  fields["value"] = r.hit ? Number(r.value) : Null();
  fields["label"] = Null();
  if (r.label) {
    auto& label = *fields["label"].mutable_struct_value()->mutable_fields();
    label["value"] = Number(float(r.label->value));
    label["name"].set_string_value(r.label->name);
  }
  return out;
}

std::string Readable(const PickResult& r, const PickOptions& o, const std::string& unit, double pick_ms) {
  if (!r.hit) return fmt::format("pixel ({}, {}): no hit at opacity {} ({:.3f} ms)", o.x, o.y, o.threshold, pick_ms);
  const std::string label = r.label ? fmt::format(", label {} \"{}\"", r.label->value, r.label->name) : "";
  return fmt::format(
      "pixel ({}, {}): LPS ({:.2f}, {:.2f}, {:.2f}) mm, value {:g}{}{}, {:.1f} mm from the eye "
      "({:.3f} ms)",
      o.x, o.y, r.position_lps.x, r.position_lps.y, r.position_lps.z, r.value, unit.empty() ? "" : " " + unit, label,
      r.distance_mm, pick_ms);
}

void Run(const PickOptions& o) {
  OfflineScene loaded = LoadOfflineScene(o.source);
  loaded.scene.clear_lights();  // a pick follows rays to the first hit: no light, no environment map read
  const Picker picker(loaded.volume, loaded.labels, ResolveScene(loaded.scene, *loaded.volume, loaded.labels.get()));
  PickSettings settings;
  settings.threshold = o.threshold;
  const auto start = std::chrono::steady_clock::now();
  const PickResult r = picker.PickPixel(o.x, o.y, settings);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (o.json) return PrintJson(PickJson(r, o));
  fmt::print("{}\n", Readable(r, o, loaded.volume->metadata().value_unit, ms));
}

}  // namespace

void AddPickCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("pick", "What the ray through a pixel of a scene's view meets, no server");
  auto o = std::make_shared<PickOptions>();
  AddSceneSource(cmd, o->source, SceneFlags::kWithPresetAndSize);
  cmd->add_option("--x", o->x, "Pixel column, from the left of the scene's viewport")->required();
  cmd->add_option("--y", o->y, "Pixel row, from the top")->required();
  cmd->add_option("--threshold", o->threshold, "Accumulated opacity at which the ray stops, (0, 1] (default 0.5)")
      ->check(CLI::Range(0.0f, 1.0f));
  cmd->add_flag("--json", o->json, "Print one JSON object: hit, position (LPS mm), value, label, pixel");
  cmd->callback([o] { Run(*o); });
}

}  // namespace cinevol::cli

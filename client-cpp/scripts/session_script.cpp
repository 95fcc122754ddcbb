// Script parsing: each line through protobuf's JSON mapping, so field errors
// name the field as the proto spells it.
#include "session_script.h"

#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "core/error.h"
#include "scene/scene_file.h"

namespace cinevol::cli {
namespace {

using google::protobuf::Message;
using google::protobuf::Struct;
using google::protobuf::Value;

std::string ToJson(const Message& message) {
  std::string json;
  google::protobuf::util::MessageToJsonString(message, &json);
  return json;
}

// Parses `json` into `message`; the error names what protobuf found wrong.
void ParseInto(const std::string& json, Message& message, const std::string& where) {
  const auto status = google::protobuf::util::JsonStringToMessage(json, &message);
  if (!status.ok()) throw InputError(fmt::format("{}: {}", where, status.message().as_string()));
}

double Number(const Value& v, const std::string& where) {
  if (v.kind_case() != Value::kNumberValue || !std::isfinite(v.number_value())) {
    throw InputError(fmt::format("{}: must be a number", where));
  }
  return v.number_value();
}

Orbit ParseOrbit(const Value& value, const std::string& where) {
  if (!value.has_struct_value()) throw InputError(where + ": must be an object");
  Orbit orbit;
  for (const auto& [key, v] : value.struct_value().fields()) {
    const std::string field = where + "." + key;
    if (key == "degrees") {
      orbit.degrees = Number(v, field);
    } else if (key == "seconds") {
      orbit.seconds = Number(v, field);
      if (orbit.seconds <= 0) throw InputError(field + ": must be > 0");
    } else if (key == "hz") {
      orbit.hz = Number(v, field);
      if (orbit.hz <= 0 || orbit.hz > 1000) throw InputError(field + ": must be in (0, 1000]");
    } else if (key == "startDegrees") {
      orbit.start_degrees = Number(v, field);
    } else if (key == "elevationDegrees") {
      orbit.elevation_degrees = Number(v, field);
      if (std::abs(orbit.elevation_degrees) >= 90) throw InputError(field + ": must be in (-90, 90)");
    } else if (key == "distanceScale") {
      orbit.distance_scale = Number(v, field);
      if (orbit.distance_scale <= 0) throw InputError(field + ": must be > 0");
    } else {
      throw InputError(fmt::format(
          "{}: unknown field (degrees, seconds, hz, startDegrees, elevationDegrees, distanceScale)", field));
    }
  }
  return orbit;
}

// "upload": a local file, checked before anything is sent.
std::filesystem::path UploadPath(const std::string& file, const std::string& field,
                                 const std::filesystem::path& base_dir) {
  const std::filesystem::path path = base_dir / file;
  if (!std::filesystem::is_regular_file(path)) {
    throw InputError(fmt::format("{}: {}: not a file that can be read", field, path.string()));
  }
  return path;
}

ScriptLabels ParseLabels(const Value& value, const std::string& where, const std::filesystem::path& base_dir) {
  if (!value.has_struct_value()) throw InputError(where + ": must be an object");
  ScriptLabels labels;
  std::string table;
  for (const auto& [key, v] : value.struct_value().fields()) {
    const std::string field = where + "." + key;
    if (v.kind_case() != Value::kStringValue) throw InputError(field + ": must be a string");
    if (key == "load") {
      labels.load = v.string_value();
    } else if (key == "upload") {
      labels.upload = UploadPath(v.string_value(), field, base_dir);
    } else if (key == "table") {
      table = v.string_value();
    } else {
      throw InputError(fmt::format("{}: unknown field (load, upload, table)", field));
    }
  }
  if (labels.load.empty() == labels.upload.empty()) throw InputError(where + ": give one of load and upload");
  if (!table.empty()) {
    if (labels.upload.empty()) {
      labels.server_table = table;
    } else {
      labels.local_table = UploadPath(table, where + ".table", base_dir);
    }
  }
  return labels;
}

ScriptSession ParseSession(const Value& value, const std::string& where, const std::filesystem::path& base_dir) {
  if (!value.has_struct_value()) throw InputError(where + ": must be an object");
  ScriptSession s;
  s.viewport.set_width(640);
  s.viewport.set_height(360);
  int volumes_named = 0;
  for (const auto& [key, v] : value.struct_value().fields()) {
    const std::string field = where + "." + key;
    const bool text = key == "volume" || key == "load" || key == "upload" || key == "preset" || key == "scene";
    if (text && v.kind_case() != Value::kStringValue) throw InputError(field + ": must be a string");
    if (key == "volume" || key == "load" || key == "upload" || key == "series") ++volumes_named;
    if (key == "volume") {
      s.volume = v.string_value();
    } else if (key == "load") {
      s.load = v.string_value();
    } else if (key == "upload") {
      s.upload = UploadPath(v.string_value(), field, base_dir);
    } else if (key == "preset") {
      s.preset = v.string_value();
    } else if (key == "scene") {
      const std::filesystem::path path = base_dir / v.string_value();
      try {
        s.scene = LoadSceneFile(path);
      } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", field, e.what()));
      }
      SayWhenUnlit(*s.scene, path.string());
    } else if (key == "viewport") {
      ParseInto(ToJson(v), s.viewport, field);
    } else if (key == "stream") {
      ParseInto(ToJson(v), s.stream, field);
    } else if (key == "labels") {
      s.labels = ParseLabels(v, field, base_dir);
    } else if (key == "series") {
      v1::LoadSeriesRequest series;
      ParseInto(ToJson(v), series, field);
      if (series.pacs().empty() || series.study_uid().empty() || series.series_uid().empty()) {
        throw InputError(field + ": give pacs, studyUid and seriesUid");
      }
      s.series = std::move(series);
    } else {
      throw InputError(fmt::format(
          "{}: unknown field (volume, load, upload, series, preset, scene, viewport, stream, labels)", field));
    }
  }
  if (volumes_named > 1) throw InputError(where + ": name the volume once: volume, load, upload or series");
  return s;
}

// "out": a file name the player writes under its slices/ folder, and nowhere else.
std::string SliceFileName(const Value& value, const std::string& where) {
  if (value.kind_case() != Value::kStringValue) throw InputError(where + ": must be a string");
  const std::string& name = value.string_value();
  const bool plain = name.find('/') == std::string::npos && name.find('\\') == std::string::npos &&
                     name.find("..") == std::string::npos &&
                     std::none_of(name.begin(), name.end(), [](unsigned char c) { return c < 0x20; });
  if (!plain || name.size() <= 4 || name.compare(name.size() - 4, 4, ".png") != 0) {
    throw InputError(
        fmt::format("{}: '{}' is not a file name ending in .png (no '/' or '..': it is written in the "
                    "run's slices/ folder)",
                    where, name));
  }
  return name;
}

// A "slice" line: a SliceRequest in proto3 JSON plus "out". Its enums may be
// written as the command line writes them ("axial" for "AXIAL").
ScriptCall ParseSlice(const Value& value, const std::string& where) {
  if (!value.has_struct_value()) throw InputError(where + ": must be an object");
  Struct request = value.struct_value();
  auto& fields = *request.mutable_fields();
  ScriptCall call;
  const auto out = fields.find("out");
  if (out == fields.end()) throw InputError(where + ".out: missing (the PNG's file name, written in slices/)");
  call.out = SliceFileName(out->second, where + ".out");
  fields.erase("out");
  for (const char* key : {"axis", "projection"}) {
    const auto it = fields.find(key);
    if (it == fields.end() || it->second.kind_case() != Value::kStringValue) continue;
    std::string name = it->second.string_value();
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::toupper(c); });
    it->second.set_string_value(name);
  }
  ParseInto(ToJson(request), call.slice.emplace(), where);
  if (!call.slice->session_id().empty()) throw InputError(where + ".sessionId: set by the player, not the script");
  return call;
}

ScriptCall ParsePick(const Value& value, const std::string& where) {
  if (!value.has_struct_value()) throw InputError(where + ": must be an object");
  ScriptCall call;
  ParseInto(ToJson(value), call.pick.emplace(), where);
  if (!call.pick->session_id().empty()) throw InputError(where + ".sessionId: set by the player, not the script");
  return call;
}

}  // namespace

SessionScript ParseScript(const std::string& text, const std::string& name, const std::filesystem::path& base_dir) {
  SessionScript script;
  script.name = name;
  std::istringstream lines(text);
  int number = 0;
  bool seen_session = false;
  double last_at = 0;
  std::map<std::string, int> slice_files;  // out -> the line that writes it
  for (std::string line; std::getline(lines, line);) {
    ++number;
    const std::string where = fmt::format("{} line {}", name, number);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    Struct object;
    const auto status = google::protobuf::util::JsonStringToMessage(line, &object);
    if (!status.ok()) throw InputError(fmt::format("{}: not a JSON object: {}", where, status.message().as_string()));
    const auto& fields = object.fields();
    if (fields.count("session")) {
      if (fields.size() != 1) throw InputError(where + ": a session line holds only \"session\"");
      if (seen_session || !script.steps.empty()) throw InputError(where + ": session: must be the first line, once");
      script.session = ParseSession(fields.at("session"), where + ": session", base_dir);
      seen_session = true;
      continue;
    }
    if (!fields.count("at")) throw InputError(where + ": at: missing (seconds from the start)");
    ScriptStep step;
    step.line = number;
    step.at = Number(fields.at("at"), where + ": at");
    if (step.at < last_at) {
      throw InputError(fmt::format("{}: at: {} is before the previous line's {}; keep lines in time order", where,
                                   step.at, last_at));
    }
    last_at = step.at;
    if (fields.size() != 2) {
      throw InputError(where +
                       ": an event line holds \"at\" and one event (camera, lights, transferFunction, "
                       "render, stream, resize, clipping, pause, resume), \"orbit\", \"ui\", \"slice\" "
                       "or \"pick\"");
    }
    for (const auto& [key, value] : fields) {
      if (key == "at") continue;
      if (key == "orbit") {
        step.is_orbit = true;
        step.orbit = ParseOrbit(value, where + ": orbit");
      } else if (key == "ui") {
        if (!value.has_struct_value()) throw InputError(where + ": ui: must be an object");
        step.ui = ToJson(value);
      } else if (key == "slice") {
        step.call = ParseSlice(value, where + ": slice");
        const auto [first, fresh] = slice_files.try_emplace(step.call->out, number);
        if (!fresh) {
          throw InputError(
              fmt::format("{}: slice.out: {} is written by line {} already", where, step.call->out, first->second));
        }
      } else if (key == "pick") {
        step.call = ParsePick(value, where + ": pick");
      } else if (key == "seq") {
        throw InputError(where + ": seq: set by the player, not the script");
      } else {
        ParseInto(fmt::format("{{\"{}\": {}}}", key, ToJson(value)), step.event, where);
      }
    }
    (step.call ? script.calls : script.steps).push_back(std::move(step));
  }
  if (script.session.viewport.width() == 0) {  // no session line
    script.session.viewport.set_width(640);
    script.session.viewport.set_height(360);
  }
  return script;
}

SessionScript LoadScript(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the script", file.string()));
  std::ostringstream text;
  text << in.rdbuf();
  return ParseScript(text.str(), file.string(), std::filesystem::absolute(file).parent_path());
}

v1::Camera OrbitCamera(const v1::VolumeInfo& volume, double degrees, double elevation_degrees, double distance_scale) {
  const double ex = volume.dims().x() * volume.spacing_mm().x(), ey = volume.dims().y() * volume.spacing_mm().y(),
               ez = volume.dims().z() * volume.spacing_mm().z();
  const double radius = 0.5 * std::sqrt(ex * ex + ey * ey + ez * ez);
  // 1.02 radii over sin(15 degrees) fits the volume in a 30 degree field of view.
  const double distance = distance_scale * 1.02 * radius / std::sin(15.0 * M_PI / 180.0);
  const double a = degrees * M_PI / 180.0, e = elevation_degrees * M_PI / 180.0;
  v1::Camera c;
  c.mutable_eye()->set_x(float(distance * std::cos(e) * std::sin(a)));
  c.mutable_eye()->set_y(float(-distance * std::cos(e) * std::cos(a)));
  c.mutable_eye()->set_z(float(distance * std::sin(e)));
  c.mutable_target();
  c.mutable_up()->set_z(1);
  c.set_fov_y_deg(30);
  return c;
}

std::vector<ScriptStep> ExpandOrbits(const std::vector<ScriptStep>& steps, const v1::VolumeInfo& volume) {
  std::vector<ScriptStep> out;
  for (const ScriptStep& s : steps) {
    if (!s.is_orbit) {
      out.push_back(s);
      continue;
    }
    const int count = std::max(1, static_cast<int>(std::lround(s.orbit.seconds * s.orbit.hz)));
    for (int i = 0; i <= count; ++i) {
      ScriptStep camera;
      camera.at = s.at + s.orbit.seconds * i / count;
      camera.line = s.line;
      *camera.event.mutable_camera() = OrbitCamera(volume, s.orbit.start_degrees + s.orbit.degrees * i / count,
                                                   s.orbit.elevation_degrees, s.orbit.distance_scale);
      out.push_back(std::move(camera));
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const ScriptStep& a, const ScriptStep& b) { return a.at < b.at; });
  return out;
}

std::vector<ScriptStep> WithCalls(std::vector<ScriptStep> steps, const std::vector<ScriptStep>& calls) {
  steps.insert(steps.end(), calls.begin(), calls.end());
  std::stable_sort(steps.begin(), steps.end(), [](const ScriptStep& a, const ScriptStep& b) {
    return a.at < b.at || (a.at == b.at && a.line < b.line);
  });
  return steps;
}

void SayWhenUnlit(const v1::Scene& scene, const std::string& file) {
  if (scene.lights_size() > 0) return;
  std::fprintf(stderr, "%s: no lights: the session takes the volume's default lights (a key light and a sky)\n",
               file.c_str());
}

v1::CreateSessionRequest SessionRequest(const ScriptSession& session, const std::string& volume_id) {
  v1::CreateSessionRequest request;
  request.set_volume_id(volume_id);
  *request.mutable_viewport() = session.viewport;
  if (session.scene) {
    *request.mutable_scene() = *session.scene;
  } else if (!session.preset.empty()) {
    request.set_preset(session.preset);
  }  // neither: the server applies the volume's default preset
  *request.mutable_stream() = session.stream;
  return request;
}

}  // namespace cinevol::cli

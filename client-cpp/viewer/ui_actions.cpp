// Session-script "ui" lines: the viewer's own actions, so that a script can
// drive the window as a person would (docs/viewer.md lists them). Each is
// checked when the script loads, and runs when its time comes.
#include "viewer/ui_actions.h"

#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <cctype>
#include <cmath>
#include <initializer_list>
#include <map>

#include "core/error.h"
#include "viewer/reading_view.h"
#include "viewer/script_runner.h"
#include "viewer/second_volume.h"
#include "viewer/transfer_edits.h"

namespace cinevol::viewer {
namespace {

using google::protobuf::Struct;
using google::protobuf::Value;

const Value& Field(const Struct& s, const std::string& key, const std::string& where) {
  const auto it = s.fields().find(key);
  if (it == s.fields().end()) throw InputError(fmt::format("{}: {}: missing", where, key));
  return it->second;
}

double Number(const Struct& s, const std::string& key, const std::string& where, double fallback = NAN) {
  const auto it = s.fields().find(key);
  if (it == s.fields().end() && !std::isnan(fallback)) return fallback;
  const Value& v = Field(s, key, where);
  if (v.kind_case() != Value::kNumberValue || !std::isfinite(v.number_value())) {
    throw InputError(fmt::format("{}: {}: must be a number", where, key));
  }
  return v.number_value();
}

std::string Text(const Value& v, const std::string& where) {
  if (v.kind_case() != Value::kStringValue) throw InputError(where + ": must be a string");
  return v.string_value();
}

const Struct& Object(const Value& v, const std::string& where) {
  if (!v.has_struct_value()) throw InputError(where + ": must be an object");
  return v.struct_value();
}

// An action's object as a PacsService request, in the request's own JSON
// names ("patientId", "studyUid"), with the fields it must name.
template <class Request>
Request PacsRequest(const Value& value, const std::string& where, std::initializer_list<const char*> required) {
  const Struct& fields = Object(value, where);
  for (const char* key : required) {
    if (Text(Field(fields, key, where), where + "." + key).empty()) {
      throw InputError(fmt::format("{}.{}: empty", where, key));
    }
  }
  std::string json;
  google::protobuf::util::MessageToJsonString(fields, &json);
  Request request;
  if (const auto status = google::protobuf::util::JsonStringToMessage(json, &request); !status.ok()) {
    throw InputError(fmt::format("{}: {}", where, status.message().as_string()));
  }
  return request;
}

bool* Panel(PanelsOpen& p, const std::string& name) {
  if (name == "volume") return &p.volume;
  if (name == "time") return &p.time;
  if (name == "secondVolume") return &p.fusion;
  if (name == "pacs") return &p.pacs;
  if (name == "transferFunction") return &p.transfer_function;
  if (name == "lights") return &p.lights;
  if (name == "render") return &p.render;
  if (name == "clipping") return &p.clipping;
  if (name == "labels") return &p.labels;
  if (name == "scene") return &p.scene;
  if (name == "reading") return &p.reading;
  if (name == "share") return &p.share;
  if (name == "stats") return &p.stats;
  return nullptr;
}

int SlicePaneIndex(const std::string& name, const std::string& where) {
  if (name == "axial") return 0;
  if (name == "coronal") return 1;
  if (name == "sagittal") return 2;
  throw InputError(where + ".pane: axial, coronal or sagittal");
}

int Button(const std::string& name, const std::string& where) {
  if (name == "left") return SDL_BUTTON_LEFT;
  if (name == "middle") return SDL_BUTTON_MIDDLE;
  if (name == "right") return SDL_BUTTON_RIGHT;
  throw InputError(where + ": button: left, middle or right");
}

bool Flag(const Struct& s, const std::string& key, const std::string& where) {
  const auto it = s.fields().find(key);
  if (it == s.fields().end()) return false;
  if (it->second.kind_case() != Value::kBoolValue) throw InputError(fmt::format("{}: {}: true or false", where, key));
  return it->second.bool_value();
}

// {"link": true} or {"principal": "bob"}, "role", "expiresSeconds", "allowPointer".
v1::ShareSessionRequest ShareRequest(const Struct& s, const std::string& where) {
  v1::ShareSessionRequest request;
  const bool link = Flag(s, "link", where);
  if (s.fields().count("principal")) request.set_principal(Text(s.fields().at("principal"), where + ".principal"));
  if (link == !request.principal().empty())
    throw InputError(where + ": \"link\": true or a \"principal\" (one of them)");
  const std::string role = s.fields().count("role") ? Text(s.fields().at("role"), where + ".role") : "viewer";
  if (role != "viewer" && role != "presenter") throw InputError(where + ".role: viewer or presenter");
  request.set_role(role == "presenter" ? v1::PRESENTER : v1::VIEWER);
  const double expires = Number(s, "expiresSeconds", where, 0);
  if (expires < 0 || expires > 604800) throw InputError(where + ".expiresSeconds: [1, 604800]; 0 or none: 2 hours");
  request.set_expires_seconds(std::uint32_t(expires));
  request.set_allow_pointer(Flag(s, "allowPointer", where));
  return request;
}

SDL_Keymod Modifier(const std::string& name, const std::string& where) {
  if (name.empty()) return KMOD_NONE;
  if (name == "shift") return KMOD_LSHIFT;
  if (name == "ctrl") return KMOD_LCTRL;
  if (name == "alt") return KMOD_LALT;
  throw InputError(where + ": modifier: shift, ctrl or alt");
}

// A movie action's path, as the Scene panel's combo offers them: "sweep": an
// axis, "phases": true the loop of a time series, neither a whole orbit.
v1::MovieRequest MoviePath(const Struct& p, const std::string& at) {
  v1::MovieRequest request;
  const bool sweep = p.fields().contains("sweep");
  if (Flag(p, "phases", at)) {
    if (sweep) throw InputError(at + ": \"sweep\" or \"phases\", not both");
    request.set_phases(true);
  } else if (!sweep) {
    request.set_orbit_degrees(360);
  } else {
    const std::string axis = Text(p.fields().at("sweep"), at + ".sweep");
    if (axis != "axial" && axis != "coronal" && axis != "sagittal") {
      throw InputError(at + ".sweep: axial, coronal or sagittal");
    }
    request.set_sweep(axis == "axial" ? v1::AXIAL : axis == "coronal" ? v1::CORONAL : v1::SAGITTAL);
  }
  return request;
}

// Transfer-function edits start from the points shown; those of a preset
// asked for before them come first (the script runner waits for them).
ShownSession& session(ActionTarget& t) { return t.rooms.link.shown(); }

UiAction ParseTransferEdit(const std::string& name, const Value& value, const std::string& at) {
  if (name == "movePoint") {  // {"movePoint": {"index": 2, "value": 300, "opacity": 0.8}}
    const Struct& p = Object(value, at);
    const int index = int(Number(p, "index", at));
    const float v = float(Number(p, "value", at)), o = float(Number(p, "opacity", at));
    return [=](ActionTarget& t) {
      v1::TransferFunction tf = session(t).scene().transfer_function();
      if (!MoveTransferPoint(tf, index, v, o)) {
        throw InputError(fmt::format("{}: no point {} (the transfer function has {})", at, index, tf.points_size()));
      }
      session(t).SetTransferFunction(tf);
    };
  }
  if (name == "addPoint") {  // {"addPoint": {"value": 300, "opacity": 0.5}}
    const Struct& p = Object(value, at);
    const float v = float(Number(p, "value", at)), o = float(Number(p, "opacity", at));
    return [=](ActionTarget& t) {
      v1::TransferFunction tf = session(t).scene().transfer_function();
      if (AddTransferPoint(tf, v, o) >= 0) session(t).SetTransferFunction(tf);
    };
  }
  if (name == "deletePoint") {  // {"deletePoint": 1}
    if (value.kind_case() != Value::kNumberValue) throw InputError(at + ": must be a point index");
    return [=, index = int(value.number_value())](ActionTarget& t) {
      v1::TransferFunction tf = session(t).scene().transfer_function();
      if (DeleteTransferPoint(tf, index)) session(t).SetTransferFunction(tf);
    };
  }
  // {"windowLevel": {"level": 100, "window": 1.5}}
  const Struct& p = Object(value, at);
  const float level = float(Number(p, "level", at, 0)), window = float(Number(p, "window", at, 1));
  return [=](ActionTarget& t) {
    v1::TransferFunction tf = session(t).scene().transfer_function();
    ApplyWindowLevel(tf, level, window);
    session(t).SetTransferFunction(tf);
  };
}

// {"secondVolume": {"opacity": 0.8, "colorMap": "RAINBOW", "window": 2000, "level": 1000, "glow": false}}:
// the Second volume panel's controls, the fields named changed over the fusion shown.
UiAction ParseSecondVolume(const Value& value, const std::string& at) {
  const Struct& p = Object(value, at);
  const auto named = [&](const char* key) { return p.fields().contains(key); };
  v1::FusionOverlay overlay;  // merged over the overlay shown: only the fields set change
  if (named("opacity")) overlay.set_opacity(float(Number(p, "opacity", at)));
  if (named("colorMap")) {
    std::string text = Text(p.fields().at("colorMap"), at + ".colorMap");
    for (char& c : text) c = char(std::toupper(static_cast<unsigned char>(c)));
    v1::ColorMap map;
    if (!v1::ColorMap_Parse(text, &map) || map == v1::COLOR_MAP_UNSPECIFIED) {
      throw InputError(at + ".colorMap: HOT, RAINBOW or GRAY");
    }
    overlay.set_color_map(map);
  }
  if (named("window") || named("level")) {  // together, as the server takes them
    overlay.set_window(float(Number(p, "window", at)));
    overlay.set_level(float(Number(p, "level", at)));
  }
  const std::optional<bool> glow = named("glow") ? std::optional(Flag(p, "glow", at)) : std::nullopt;
  return [=](ActionTarget& t) {
    v1::Fusion fusion = session(t).scene().fusion();
    if (!Fuses(session(t).scene())) throw InputError(at + ": the session fuses no second volume (--fuse)");
    fusion.mutable_overlay()->MergeFrom(overlay);
    if (glow) {
      const std::optional<v1::VolumeInfo>& fused = t.rooms.link.fused_volume();
      if (!fused) throw InputError(at + ".glow: the second volume's description is not known here");
      SetGlow(fusion, *glow, *fused);
    }
    session(t).SetFusion(fusion);
  };
}

// The PACS panel's actions; none for another name.
UiAction ParsePacsAction(const std::string& name, const Value& value, const std::string& at) {
  if (name == "searchPacs") {  // {"searchPacs": {"pacs": "main", "patientId": "123", "modality": "CT"}}
    const auto query = PacsRequest<v1::SearchStudiesRequest>(value, at, {"pacs"});
    return [query](ActionTarget& t) {
      t.rooms.panels.pacs = true;  // a screenshot shows what the panel found
      t.rooms.pacs.Search(query);
    };
  }
  if (name == "selectStudy") {  // {"selectStudy": {"pacs": "main", "studyUid": "1.2.3"}}
    const auto study = PacsRequest<v1::SearchSeriesRequest>(value, at, {"pacs", "studyUid"});
    return [study](ActionTarget& t) {
      t.rooms.panels.pacs = true;
      t.rooms.pacs.SelectStudy(study.pacs(), study.study_uid());
    };
  }
  if (name == "storeMeasurements") {  // {"storeMeasurements": {"pacs": "main"}}
    const auto store = PacsRequest<v1::StoreMeasurementsRequest>(value, at, {"pacs"});
    return [store](ActionTarget& t) {
      t.rooms.panels.pacs = true;
      t.rooms.pacs.StoreMeasurements(store.pacs());
    };
  }
  if (name == "openSeries") {  // {"openSeries": {"pacs": "main", "studyUid": "1.2.3", "seriesUid": "1.2.3.4"}}
    const auto series = PacsRequest<v1::LoadSeriesRequest>(value, at, {"pacs", "studyUid", "seriesUid"});
    return [series](ActionTarget& t) {
      t.rooms.panels.pacs = true;
      t.rooms.pacs.OpenSeries(series);
    };
  }
  return {};
}

// A fraction of a view's width or height, as a click names it.
double Fraction(const Struct& p, const std::string& key, const std::string& at) {
  const double f = Number(p, key, at);
  if (f < 0 || f >= 1) throw InputError(at + ": x and y in [0, 1)");
  return f;
}

// The reading tools' actions; none for another name.
UiAction ParseReadingAction(const std::string& name, const Value& value, const std::string& at) {
  if (name == "layout2x2") {  // {"layout2x2": true}: the 3D view and three slices; false: the 3D view only
    if (value.kind_case() != Value::kBoolValue) throw InputError(at + ": true or false");
    return [grid = value.bool_value()](ActionTarget& t) {
      if (t.rooms.reading.grid != grid) t.rooms.reading.ToggleGrid();
    };
  }
  if (name == "pickAt") {  // {"pickAt": {"x": 0.5, "y": 0.5}}: a click there, in fractions of the 3D view
    const Struct& p = Object(value, at);
    const double x = Fraction(p, "x", at), y = Fraction(p, "y", at);
    return [x, y](ActionTarget& t) {
      const Rect shown = t.rooms.screen.ShownFrame();
      t.rooms.reading.PickAt(shown.x + float(x) * shown.w, shown.y + float(y) * shown.h);
    };
  }
  if (name == "clickSlice" || name == "stepSlice") {
    // {"clickSlice": {"pane": "axial", "x": 0.5, "y": 0.5}}, {"stepSlice": {"pane": "coronal", "steps": 2}}
    const Struct& p = Object(value, at);
    const int pane = SlicePaneIndex(Text(Field(p, "pane", at), at + ".pane"), at);
    if (name == "stepSlice") {
      return [pane, steps = float(Number(p, "steps", at))](ActionTarget& t) { t.rooms.reading.StepSlice(pane, steps); };
    }
    const double x = Fraction(p, "x", at), y = Fraction(p, "y", at);
    return [pane, x, y](ActionTarget& t) {
      const Rect shown = t.rooms.reading.ShownSlice(pane);
      t.rooms.reading.ClickSlice(pane, shown.x + float(x) * shown.w, shown.y + float(y) * shown.h);
    };
  }
  if (name == "measureDistance" || name == "measureAngle") {  // {"measureAngle": true}: the next 3 picks
    return [points = name == "measureAngle" ? kAnglePoints : kDistancePoints](ActionTarget& t) {
      t.rooms.reading.StartMeasurement(points);
    };
  }
  if (name == "deleteMeasurement") {  // {"deleteMeasurement": 0}: its x button in the Reading panel
    if (value.kind_case() != Value::kNumberValue) throw InputError(at + ": must be a measurement index");
    return [index = int(value.number_value())](ActionTarget& t) { t.rooms.reading.DeleteMeasurement(index); };
  }
  return {};
}

// Sharing's actions; none for another name.
UiAction ParseSharingAction(const std::string& name, const Value& value, const std::string& at) {
  if (name == "share") {  // {"share": {"link": true, "role": "viewer", "allowPointer": true}}
    const v1::ShareSessionRequest request = ShareRequest(Object(value, at), at);
    return [request, at](ActionTarget& t) {
      if (t.rooms.link.Watching()) throw InputError(at + ": only the session's owner shares it (this viewer has --grant)");
      t.rooms.panels.share = true;  // a screenshot shows the secret and the grants
      t.rooms.sharing.Share(request);
    };
  }
  if (name == "handover" || name == "revoke") {  // {"handover": {"grant": "g..."}}; "last": the newest made here
    const std::string grant = Text(Field(Object(value, at), "grant", at), at + ".grant");
    if (name == "revoke" && grant.empty()) throw InputError(at + ".grant: a grant's id, or \"last\"");
    return [name, grant, at](ActionTarget& t) {
      Sharing& sharing = t.rooms.sharing;
      if (t.rooms.link.Watching() && !(name == "handover" && grant.empty())) {
        throw InputError(at + ": a grant's holder only gives the presenter's role back (\"grant\": \"\")");
      }
      std::string id = grant;
      if (grant == "last") {
        if (!sharing.made) throw InputError(at + ": no grant made yet (\"last\")");
        id = sharing.made->id();
      }
      name == "handover" ? sharing.HandOver(id) : sharing.Revoke(id);
    };
  }
  if (name == "listShares") {  // {"listShares": true}
    return [at](ActionTarget& t) {
      if (t.rooms.link.Watching()) throw InputError(at + ": only the session's owner lists its grants");
      t.rooms.sharing.ListShares();
    };
  }
  if (name == "pointer") {  // {"pointer": {"x": 0.2, "y": 0.4}}: the mouse there over the 3D view
    const Struct& p = Object(value, at);
    std::optional<PointerShare::At> where;  // {"pointer": {"hidden": true}}: it left the view
    if (!Flag(p, "hidden", at)) {
      const double x = Number(p, "x", at), y = Number(p, "y", at);
      if (x < 0 || x > 1 || y < 0 || y > 1) throw InputError(at + ": x and y in [0, 1]");
      where = PointerShare::At{float(x), float(y)};
    }
    return [where](ActionTarget& t) { t.rooms.sharing.PointAt(where); };
  }
  return {};
}

}  // namespace

UiAction ParseUiAction(const std::string& json, const std::string& where) {
  Struct action;
  if (!google::protobuf::util::JsonStringToMessage(json, &action).ok() || action.fields().size() != 1) {
    throw InputError(where + ": one action per line");
  }
  const auto& [name, value] = *action.fields().begin();
  const std::string at = where + "." + name;
  if (name == "panel") {  // {"panel": {"name": "lights", "open": true}}
    const Struct& p = Object(value, at);
    const std::string panel = Text(Field(p, "name", at), at + ".name");
    if (PanelsOpen all; !Panel(all, panel)) {
      throw InputError(at +
                       ".name: volume, pacs, time, secondVolume, transferFunction, lights, render, clipping, labels, "
                       "reading, scene, share or stats");
    }
    const bool open = !p.fields().count("open") || p.fields().at("open").bool_value();
    return [panel, open](ActionTarget& t) { *Panel(t.rooms.panels, panel) = open; };
  }
  if (name == "key") {  // {"key": "p"}
    const std::string key = Text(value, at);
    static const std::map<std::string, SDL_Keycode> kNamed = {
        {"Home", SDLK_HOME}, {"F2", SDLK_F2}, {"F3", SDLK_F3}, {"F4", SDLK_F4}};
    if (key.size() != 1 && !kNamed.count(key)) throw InputError(at + ": one character, Home, F2, F3 or F4");
    const SDL_Keycode code = key.size() == 1 ? SDL_Keycode(std::tolower(key[0])) : kNamed.at(key);
    return [code](ActionTarget& t) { t.input.Key(code); };
  }
  if (name == "drag") {  // {"drag": {"button": "left", "dx": 100, "dy": 0, "modifier": "ctrl"}}
    const Struct& d = Object(value, at);
    const int button = Button(d.fields().count("button") ? Text(d.fields().at("button"), at) : "left", at);
    const SDL_Keymod mods = Modifier(d.fields().count("modifier") ? Text(d.fields().at("modifier"), at) : "", at);
    const float dx = float(Number(d, "dx", at, 0)), dy = float(Number(d, "dy", at, 0));
    return [=](ActionTarget& t) { t.input.Drag(button, dx, dy, mods); };
  }
  if (name == "wheel") {  // {"wheel": 2}
    if (value.kind_case() != Value::kNumberValue) throw InputError(at + ": must be a number");
    return [steps = float(value.number_value())](ActionTarget& t) { t.input.Wheel(steps); };
  }
  if (name == "preset") {  // the server fits it to the volume
    return [preset = Text(value, at)](ActionTarget& t) { t.rooms.link.shown().ChoosePreset(preset); };
  }
  if (name == "movePoint" || name == "addPoint" || name == "deletePoint" || name == "windowLevel") {
    return ParseTransferEdit(name, value, at);
  }
  if (name == "secondVolume") return ParseSecondVolume(value, at);
  if (name == "snapshot") {  // {"snapshot": {"file": "still.png", "spp": 64}}
    const Struct& p = Object(value, at);
    const std::string file = Text(Field(p, "file", at), at + ".file");
    const int spp = int(Number(p, "spp", at, 256));
    return [file, spp](ActionTarget& t) { t.rooms.files.Snapshot(file, spp); };
  }
  if (name == "movie") {  // {"movie": {"file": "beat.mp4", "seconds": 2, "spp": 16, "phases": true}}
    const Struct& p = Object(value, at);
    const std::string file = Text(Field(p, "file", at), at + ".file");
    v1::MovieRequest request = MoviePath(p, at);
    request.set_seconds(Number(p, "seconds", at, 4));
    request.set_spp(std::uint32_t(Number(p, "spp", at, 32)));
    return [file, request](ActionTarget& t) { t.rooms.files.Movie(file, request); };
  }
  if (name == "saveScene" || name == "openScene") {
    const std::string file = Text(value, at);
    if (name == "saveScene") return [file](ActionTarget& t) { t.rooms.files.Save(file); };
    return [file](ActionTarget& t) { t.rooms.files.Open(file); };
  }
  if (name == "resizeWindow") {  // {"resizeWindow": {"width": 800, "height": 500}}
    const Struct& p = Object(value, at);
    const double w = Number(p, "width", at), h = Number(p, "height", at);
    if (w < 200 || h < 150 || w > 8192 || h > 8192) {
      throw InputError(at + ": width and height in [200, 8192] x [150, 8192]");
    }
    return [w, h](ActionTarget& t) { t.rooms.screen.Resize(int(w), int(h)); };
  }
  if (name == "screenshot") {  // {"screenshot": "step.png"}: the window once this turn is drawn
    return [file = Text(value, at)](ActionTarget& t) { t.runner.Screenshot(file); };
  }
  if (name == "settle") {  // {"settle": true}: the script waits until every event sent has its frame
    return [](ActionTarget& t) { t.runner.Settle(); };
  }
  if (name == "quit") {
    return [](ActionTarget& t) { t.runner.Finish(); };
  }
  if (UiAction pacs = ParsePacsAction(name, value, at)) return pacs;
  if (UiAction reading = ParseReadingAction(name, value, at)) return reading;
  if (UiAction sharing = ParseSharingAction(name, value, at)) return sharing;
  throw InputError(fmt::format(
      "{}: unknown action (panel, key, drag, wheel, preset, movePoint, addPoint, deletePoint, windowLevel, "
      "secondVolume, snapshot, movie, saveScene, openScene, searchPacs, selectStudy, openSeries, storeMeasurements, layout2x2, pickAt, clickSlice, "
      "stepSlice, measureDistance, measureAngle, deleteMeasurement, share, listShares, handover, revoke, pointer, "
      "resizeWindow, settle, screenshot, quit)",
      at));
}

}  // namespace cinevol::viewer

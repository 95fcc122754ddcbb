// The client library's view math against tests/golden/view_math.json, the
// cases the page's twins (web/src) meet too: a number that drifts on either
// side fails its test. With CINEVOL_WRITE_GOLDEN=FILE the cases' expected
// values are computed here and written to FILE instead (review the diff).
#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "placement.h"
#include "view_math.h"

namespace cinevol {
namespace {

using google::protobuf::ListValue;
using google::protobuf::Struct;
using google::protobuf::Value;

const char* const kGoldenFile = CINEVOL_SOURCE_DIR "/tests/golden/view_math.json";
const char* const kCategories[] = {"camera", "slice_geometry", "edge_letters", "measurement", "patient_frame"};

// ---------------------------------------------------------------- reading

Struct ReadGolden(const std::string& file) {
  std::ifstream in(file);
  const std::string json{std::istreambuf_iterator<char>(in), {}};
  Struct golden;
  const auto status = google::protobuf::util::JsonStringToMessage(json, &golden);
  if (!status.ok()) throw std::runtime_error(file + ": " + std::string(status.message()));
  return golden;
}

const Value& Field(const Struct& s, const std::string& key) {
  const auto it = s.fields().find(key);
  if (it == s.fields().end()) throw std::runtime_error("missing \"" + key + "\"");
  return it->second;
}

double Number(const Struct& s, const std::string& key) { return Field(s, key).number_value(); }

Vec3d VecOf(const Value& v) {
  const ListValue& l = v.list_value();
  if (l.values_size() != 3) throw std::runtime_error("a vector needs 3 numbers");
  return {l.values(0).number_value(), l.values(1).number_value(), l.values(2).number_value()};
}

Vec3d VecOf(const Struct& s, const std::string& key) { return VecOf(Field(s, key)); }

ViewCamera CameraOf(const Struct& s) {
  return {VecOf(s, "eye"), VecOf(s, "target"), VecOf(s, "up"), Number(s, "fov_y_deg")};
}

Placement PlacementOf(const Struct& s) {
  const ListValue& d = Field(s, "direction").list_value();
  if (d.values_size() != 9) throw std::runtime_error("direction needs 9 numbers");
  Placement::Direction direction;
  for (int i = 0; i < 9; ++i) direction[i] = d.values(i).number_value();
  return {direction, VecOf(s, "origin_mm"), VecOf(s, "spacing_mm"), VecOf(s, "dims")};
}

SliceGrid SliceOf(const Struct& s) {
  return {VecOf(s, "origin_mm"),         VecOf(s, "row_direction"),    VecOf(s, "column_direction"),
          Number(s, "row_spacing_mm"),   Number(s, "column_spacing_mm"), int(Number(s, "width")),
          int(Number(s, "height"))};
}

int AxisOf(const Struct& s) {
  const std::string axis = Field(s, "axis").string_value();
  if (axis != "x" && axis != "y" && axis != "z") throw std::runtime_error("axis: x, y or z");
  return axis[0] - 'x';
}

std::vector<Vec3d> PointsOf(const Struct& s, const std::string& key) {
  std::vector<Vec3d> points;
  for (const Value& v : Field(s, key).list_value().values()) points.push_back(VecOf(v));
  return points;
}

// --------------------------------------------------------- what is computed

Value NumberValue(double n) {
  Value v;
  v.set_number_value(n);
  return v;
}

Value VecValue(Vec3d p) {
  Value v;
  for (int i = 0; i < 3; ++i) *v.mutable_list_value()->add_values() = NumberValue(p[i]);
  return v;
}

Value CameraValue(const ViewCamera& c) {
  Value v;
  auto& f = *v.mutable_struct_value()->mutable_fields();
  f["eye"] = VecValue(c.eye);
  f["target"] = VecValue(c.target);
  f["up"] = VecValue(c.up);
  f["fov_y_deg"] = NumberValue(c.fov_y_deg);
  return v;
}

Value TextValue(const std::string& text) {
  Value v;
  v.set_string_value(text);
  return v;
}

// The letters at a view's edges: the half-axis pointing most to each side.
Struct EdgesOf(const std::vector<MarkerAxis>& axes) {
  const auto most = [&](auto key) {
    return std::string(1, std::max_element(axes.begin(), axes.end(), [&](const MarkerAxis& a, const MarkerAxis& b) {
                            return key(a) < key(b);
                          })->letter);
  };
  Struct edges;
  auto& f = *edges.mutable_fields();
  f["left"] = TextValue(most([](const MarkerAxis& a) { return -a.x; }));
  f["right"] = TextValue(most([](const MarkerAxis& a) { return a.x; }));
  f["top"] = TextValue(most([](const MarkerAxis& a) { return a.y; }));
  f["bottom"] = TextValue(most([](const MarkerAxis& a) { return -a.y; }));
  return edges;
}

// What the library makes of a case's inputs, in the shape of its "expected".
Struct Compute(const Struct& c) {
  const std::string kind = Field(c, "kind").string_value();
  Struct out;
  auto& f = *out.mutable_fields();
  if (kind == "orbit_drag" || kind == "pan_drag" || kind == "zoom_drag" || kind == "wheel") {
    ViewCamera camera = CameraOf(Field(c, "camera").struct_value());
    if (kind == "orbit_drag") Orbit(camera, Number(c, "dx_px") * kDegreesPerPixel, Number(c, "dy_px") * kDegreesPerPixel);
    if (kind == "pan_drag") Pan(camera, Number(c, "dx_px"), Number(c, "dy_px"), Number(c, "viewport_height_px"));
    if (kind == "zoom_drag") Zoom(camera, DragZoomFactor(Number(c, "dy_px")));
    if (kind == "wheel") Zoom(camera, WheelZoomFactor(Number(c, "steps")));
    f["camera"] = CameraValue(camera);
  } else if (kind == "project") {
    const auto p = ProjectToView(CameraOf(Field(c, "camera").struct_value()), VecOf(c, "point"),
                                 Number(c, "width_px"), Number(c, "height_px"));
    f["visible"].set_bool_value(p.has_value());
    if (p) f["x"] = NumberValue(p->x), f["y"] = NumberValue(p->y);
  } else if (kind == "slice_plane_outline") {
    const Placement placement = PlacementOf(Field(c, "placement").struct_value());
    auto& polygon = *f["polygon"].mutable_list_value();
    for (Vec3d p : placement.SlicePlaneOutline(AxisOf(c), Number(c, "position_mm"))) *polygon.add_values() = VecValue(p);
  } else if (kind == "voxel_step") {
    f["mm"] = NumberValue(PlacementOf(Field(c, "placement").struct_value()).VoxelStepMm(AxisOf(c)));
  } else if (kind == "slice_pixel_to_patient") {
    f["lps"] = VecValue(
        SlicePixelToPatient(SliceOf(Field(c, "slice").struct_value()), Number(c, "column"), Number(c, "row")));
  } else if (kind == "patient_to_slice_pixel") {
    const SlicePixel p = PatientToSlicePixel(SliceOf(Field(c, "slice").struct_value()), VecOf(c, "lps"));
    f["column"] = NumberValue(p.column), f["row"] = NumberValue(p.row), f["off_plane_mm"] = NumberValue(p.off_plane_mm);
  } else if (kind == "marker_axes") {
    const std::vector<MarkerAxis> axes =
        MarkerAxes(CameraOf(Field(c, "camera").struct_value()), PlacementOf(Field(c, "placement").struct_value()));
    auto& list = *f["axes"].mutable_list_value();
    for (const MarkerAxis& a : axes) {
      auto& axis = *list.add_values()->mutable_struct_value()->mutable_fields();
      axis["letter"] = TextValue(std::string(1, a.letter));
      axis["x"] = NumberValue(a.x), axis["y"] = NumberValue(a.y), axis["depth"] = NumberValue(a.depth);
    }
    *f["edges"].mutable_struct_value() = EdgesOf(axes);
  } else if (kind == "distance" || kind == "angle") {
    const std::vector<Vec3d> p = PointsOf(c, "points");
    if (p.size() != (kind == "distance" ? 2u : 3u)) throw std::runtime_error("points: 2 for a distance, 3 for an angle");
    if (kind == "distance") f["mm"] = NumberValue(DistanceMm(p[0], p[1]));
    if (kind == "angle") f["deg"] = NumberValue(AngleDeg(p[0], p[1], p[2]));
  } else if (kind == "to_patient" || kind == "to_volume" || kind == "direction_to_patient" ||
             kind == "direction_to_volume") {
    const Placement placement = PlacementOf(Field(c, "placement").struct_value());
    const Vec3d p = VecOf(c, "point");
    f["point"] = VecValue(kind == "to_patient"             ? placement.ToPatient(p)
                          : kind == "to_volume"            ? placement.ToVolume(p)
                          : kind == "direction_to_patient" ? placement.DirectionToPatient(p)
                                                           : placement.DirectionToVolume(p));
  } else {
    throw std::runtime_error("unknown kind \"" + kind + "\"");
  }
  return out;
}

// ------------------------------------------------------------- comparing

// Numbers within `tolerance`, texts and booleans equal, lists as lists,
// objects key by key (every expected key present); where they part, says where.
void ExpectSame(const Value& want, const Value& got, double tolerance, const std::string& where) {
  ASSERT_EQ(want.kind_case(), got.kind_case()) << where;
  switch (want.kind_case()) {
    case Value::kNumberValue:
      EXPECT_NEAR(got.number_value(), want.number_value(), tolerance) << where;
      break;
    case Value::kStringValue:
      EXPECT_EQ(got.string_value(), want.string_value()) << where;
      break;
    case Value::kBoolValue:
      EXPECT_EQ(got.bool_value(), want.bool_value()) << where;
      break;
    case Value::kListValue:
      ASSERT_EQ(got.list_value().values_size(), want.list_value().values_size()) << where;
      for (int i = 0; i < want.list_value().values_size(); ++i) {
        ExpectSame(want.list_value().values(i), got.list_value().values(i), tolerance, fmt::format("{}[{}]", where, i));
      }
      break;
    case Value::kStructValue:
      ASSERT_EQ(got.struct_value().fields_size(), want.struct_value().fields_size()) << where;
      for (const auto& [key, value] : want.struct_value().fields()) {
        const auto it = got.struct_value().fields().find(key);
        ASSERT_NE(it, got.struct_value().fields().end()) << where << "." << key;
        ExpectSame(value, it->second, tolerance, where + "." + key);
      }
      break;
    default:
      break;
  }
}

// A polygon's corners may start anywhere and run either way round.
void ExpectSamePolygon(const ListValue& want, const ListValue& got, double tolerance, const std::string& where) {
  ASSERT_EQ(got.values_size(), want.values_size()) << where;
  const int n = want.values_size();
  if (n == 0) return;  // the plane misses the box
  const auto close = [&](const Value& a, const Value& b) {
    const Vec3d p = VecOf(a), q = VecOf(b);
    return std::fabs(p.x - q.x) <= tolerance && std::fabs(p.y - q.y) <= tolerance && std::fabs(p.z - q.z) <= tolerance;
  };
  for (int start = 0; start < n; ++start) {
    for (int way : {1, -1}) {
      bool all = true;
      for (int i = 0; i < n && all; ++i) all = close(want.values(i), got.values(((start + way * i) % n + n) % n));
      if (all) return;
    }
  }
  ADD_FAILURE() << where << ": the corners differ from the expected polygon's";
}

void ExpectSameMarker(const Struct& want, const Struct& got, double tolerance, const std::string& where) {
  std::map<std::string, Value> by_letter;
  double depth = -2;
  for (const Value& axis : Field(got, "axes").list_value().values()) {
    by_letter[Field(axis.struct_value(), "letter").string_value()] = axis;
    EXPECT_GE(Number(axis.struct_value(), "depth"), depth - tolerance) << where << ": not farthest first";
    depth = Number(axis.struct_value(), "depth");
  }
  ASSERT_EQ(by_letter.size(), 6u) << where;
  for (const Value& axis : Field(want, "axes").list_value().values()) {
    const std::string letter = Field(axis.struct_value(), "letter").string_value();
    ASSERT_TRUE(by_letter.count(letter)) << where << ": no " << letter;
    ExpectSame(axis, by_letter[letter], tolerance, where + "." + letter);
  }
  ExpectSame(Field(want, "edges"), Field(got, "edges"), tolerance, where + ".edges");
}

// ------------------------------------------------------------- writing

// Numbers as the shortest text that reads back the same double; rounding
// noise around whole numbers (-3e-14 for 0) dropped, far inside the tolerance.
std::string NumberText(double n) {
  if (std::fabs(n - std::round(n)) < 1e-9) n = std::round(n) + 0.0;  // + 0.0: no "-0"
  if (n == std::floor(n) && std::fabs(n) < 1e15) return fmt::format("{}", static_cast<long long>(n));
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text, n).ptr;
  return std::string(text, end);
}

// Keys in the order a reader expects them; others after, sorted.
int KeyRank(const std::string& key) {
  static const std::vector<std::string> kOrder = {
      "about", "tolerance", "name", "kind", "camera", "slice_geometry", "edge_letters", "measurement",
      "patient_frame", "eye", "target", "up", "fov_y_deg", "direction", "origin_mm", "spacing_mm", "dims", "placement",
      "slice", "row_direction", "column_direction", "row_spacing_mm", "column_spacing_mm", "width", "height", "axis",
      "position_mm", "dx_px", "dy_px", "viewport_height_px", "steps", "point", "points", "lps", "column", "row",
      "width_px", "height_px", "visible", "letter", "x", "y", "depth", "off_plane_mm", "polygon", "mm", "deg", "axes",
      "edges", "left", "right", "top", "bottom", "expected"};
  const auto it = std::find(kOrder.begin(), kOrder.end(), key);
  return it == kOrder.end() ? int(kOrder.size()) : int(it - kOrder.begin());
}

std::string Json(const Value& v, const std::string& indent) {
  switch (v.kind_case()) {
    case Value::kNumberValue:
      return NumberText(v.number_value());
    case Value::kBoolValue:
      return v.bool_value() ? "true" : "false";
    case Value::kStringValue: {
      std::string json = "\"";
      for (const char c : v.string_value()) {
        if (c == '"' || c == '\\') json += '\\';
        if (static_cast<unsigned char>(c) < 0x20) {
          json += fmt::format("\\u{:04x}", int(c));
        } else {
          json += c;
        }
      }
      return json + "\"";
    }
    case Value::kListValue: {
      const auto& values = v.list_value().values();
      const bool flat = std::all_of(values.begin(), values.end(), [](const Value& e) {
        return e.has_number_value() || (e.has_list_value() && e.list_value().values_size() <= 3);
      });
      std::string out = "[";
      for (int i = 0; i < values.size(); ++i) {
        out += (i ? (flat ? ", " : ",\n" + indent + "  ") : (flat ? "" : "\n" + indent + "  "));
        out += Json(values[i], indent + "  ");
      }
      return out + (flat || values.empty() ? "]" : "\n" + indent + "]");
    }
    case Value::kStructValue: {
      std::vector<std::string> keys;
      for (const auto& [key, value] : v.struct_value().fields()) keys.push_back(key);
      std::sort(keys.begin(), keys.end(), [](const std::string& a, const std::string& b) {
        return std::pair(KeyRank(a), a) < std::pair(KeyRank(b), b);
      });
      const bool small = keys.size() <= 4 && std::none_of(keys.begin(), keys.end(), [&](const std::string& k) {
        return v.struct_value().fields().at(k).has_struct_value() || k == "name" || k == "polygon" || k == "axes";
      });
      std::string out = "{";
      for (std::size_t i = 0; i < keys.size(); ++i) {
        out += i ? (small ? ", " : ",\n" + indent + "  ") : (small ? "" : "\n" + indent + "  ");
        out += "\"" + keys[i] + "\": " + Json(v.struct_value().fields().at(keys[i]), indent + "  ");
      }
      return out + (small ? "}" : "\n" + indent + "}");
    }
    default:
      return "null";
  }
}

// ---------------------------------------------------------------- tests

TEST(ViewMath, TheGoldenFileSaysWhatItHoldsAndHasEveryCategory) {
  const Struct golden = ReadGolden(kGoldenFile);
  EXPECT_GT(Field(golden, "about").string_value().size(), 200u) << "the schema is documented in \"about\"";
  EXPECT_GT(Number(golden, "tolerance"), 0);
  for (const char* category : kCategories) {
    EXPECT_GE(Field(golden, category).list_value().values_size(), 4) << category;
  }
}

TEST(ViewMath, EveryGoldenCaseIsMetByTheClientLibrary) {
  const char* write = std::getenv("CINEVOL_WRITE_GOLDEN");
  Struct golden = ReadGolden(kGoldenFile);
  const double tolerance = Number(golden, "tolerance");
  std::set<std::string> names;
  for (const char* category : kCategories) {
    for (Value& c : *(*golden.mutable_fields())[category].mutable_list_value()->mutable_values()) {
      Struct& fields = *c.mutable_struct_value();
      const std::string where = fmt::format("{}: {}", category, Field(fields, "name").string_value());
      EXPECT_TRUE(names.insert(Field(fields, "name").string_value()).second) << where << ": named twice";
      Struct got;
      try {
        got = Compute(fields);
      } catch (const std::exception& e) {
        ADD_FAILURE() << where << ": " << e.what();
        continue;
      }
      if (write) {
        *(*fields.mutable_fields())["expected"].mutable_struct_value() = got;
        continue;
      }
      const Struct& want = Field(fields, "expected").struct_value();
      const std::string kind = Field(fields, "kind").string_value();
      if (kind == "slice_plane_outline") {
        ExpectSamePolygon(Field(want, "polygon").list_value(), Field(got, "polygon").list_value(), tolerance, where);
      } else if (kind == "marker_axes") {
        ExpectSameMarker(want, got, tolerance, where);
      } else {
        Value w, g;
        *w.mutable_struct_value() = want;
        *g.mutable_struct_value() = got;
        ExpectSame(w, g, tolerance, where);
      }
    }
  }
  if (write) {
    Value all;
    *all.mutable_struct_value() = golden;
    std::ofstream(write) << Json(all, "") << "\n";
    GTEST_SKIP() << "wrote the expected values to " << write;
  }
}

// A few by hand, so that the file cannot drift with the code unnoticed.
TEST(ViewMath, HandCheckedCasesHoldTheirTextbookValues) {
  ViewCamera front{{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30};
  Orbit(front, 225 * kDegreesPerPixel, 0);  // 90 degrees: the eye goes round to the viewer's left
  EXPECT_NEAR(front.eye.x, -500, 1e-9);
  EXPECT_NEAR(front.eye.y, 0, 1e-9);
  ViewCamera near{{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30};
  Zoom(near, WheelZoomFactor(1));
  EXPECT_NEAR(near.eye.y, -450, 1e-9);
  const auto top = ProjectToView({{0, -500, 0}, {0, 0, 0}, {0, 0, 1}, 30}, {0, 0, 500 * std::tan(M_PI / 12)}, 200, 100);
  ASSERT_TRUE(top);
  EXPECT_NEAR(top->y, 0, 1e-9);
  EXPECT_DOUBLE_EQ(DistanceMm({0, 0, 0}, {3, 4, 0}), 5);
  EXPECT_NEAR(AngleDeg({1, 0, 0}, {0, 0, 0}, {0, 1, 0}), 90, 1e-12);
  // RAS-stored 11 x 21 x 31 of 1 x 1 x 2 mm at the origin: the centre is voxel (5, 10, 15): L -5, P -10, S 30.
  const Placement ras({-1, 0, 0, 0, -1, 0, 0, 0, 1}, {0, 0, 0}, {1, 1, 2}, {11, 21, 31});
  const Vec3d centre = ras.ToPatient({0, 0, 0});
  EXPECT_NEAR(centre.x, -5, 1e-12);
  EXPECT_NEAR(centre.y, -10, 1e-12);
  EXPECT_NEAR(centre.z, 30, 1e-12);
}

// The fallback for direction cosines is the identity, and it is the only one.
TEST(ViewMath, DirectionCosinesFallBackToTheIdentityWhereThereAreNotNine) {
  google::protobuf::RepeatedField<double> none, eight, nine;
  for (int i = 0; i < 8; ++i) eight.Add(1);
  for (double d : {0, 1, 0, 1, 0, 0, 0, 0, -1}) nine.Add(d);
  const Placement::Direction identity{1, 0, 0, 0, 1, 0, 0, 0, 1};
  EXPECT_EQ(Placement::DirectionOf(none), identity);
  EXPECT_EQ(Placement::DirectionOf(eight), identity);
  nine.Set(4, NAN);
  EXPECT_EQ(Placement::DirectionOf(nine), identity) << "a NaN is no direction";
  nine.Set(4, 0);
  EXPECT_EQ(Placement::DirectionOf(nine), (Placement::Direction{0, 1, 0, 1, 0, 0, 0, 0, -1}));
  v1::VolumePlacement placement;  // a placement a session sent, and the same volume's info, agree
  *placement.mutable_direction() = nine;
  placement.mutable_origin_mm()->set_x(4);
  placement.mutable_spacing_mm()->set_x(2), placement.mutable_spacing_mm()->set_y(2), placement.mutable_spacing_mm()->set_z(2);
  placement.mutable_dims()->set_x(3), placement.mutable_dims()->set_y(3), placement.mutable_dims()->set_z(3);
  v1::VolumeInfo info;
  *info.mutable_direction() = nine;
  *info.mutable_origin_mm() = placement.origin_mm();
  *info.mutable_spacing_mm() = placement.spacing_mm();
  *info.mutable_dims() = placement.dims();
  const Vec3d a = Placement::Of(placement).ToPatient({1, 2, 3}), b = Placement::Of(info).ToPatient({1, 2, 3});
  EXPECT_EQ(a, b);
  EXPECT_EQ(a, (Vec3d{4 + 2 + 2, 1 + 2, -(3 + 2)}));
}

// A scene file keeps camera and lights in patient coordinates; the session
// takes them in the volume-centred frame. There and back is where it began.
TEST(ViewMath, AScenesCameraAndLightsGoToThePatientAndBack) {
  const Placement oblique({0.8660254037844387, -0.5, 0, 0.46984631039295416, 0.8137976813493738, 0.3420201433256687,
                           0.17101007166283433, 0.29619813272602386, -0.9396926207859084},
                          {-50, 40, -10}, {1, 1.2, 2.5}, {40, 50, 20});
  v1::Scene scene;
  *scene.mutable_camera() = ToProto(ViewCamera{{10, -300, 20}, {1, 2, 3}, {0, 0, 1}, 30});
  v1::AreaLight& light = *scene.add_lights()->mutable_area();
  *light.mutable_center() = ToProto(Vec3d{0, -200, 100});
  *light.mutable_edge_u() = ToProto(Vec3d{50, 0, 0});
  *light.mutable_edge_v() = ToProto(Vec3d{0, 0, 50});
  const v1::Scene before = scene;
  MoveSceneToPatient(scene, oblique);
  EXPECT_EQ(scene.frame(), v1::PATIENT_LPS);
  const Vec3d eye = ToVec3d(scene.camera().eye()), want = oblique.ToPatient({10, -300, 20});
  EXPECT_NEAR(Length(eye - want), 0, 1e-3);
  MoveSceneToPatient(scene, oblique);  // there already: stays
  EXPECT_NEAR(Length(ToVec3d(scene.camera().eye()) - want), 0, 1e-3);
  MoveSceneToVolumeCentred(scene, oblique);
  EXPECT_EQ(scene.frame(), v1::SCENE_FRAME_UNSPECIFIED);
  EXPECT_NEAR(Length(ToVec3d(scene.camera().eye()) - ToVec3d(before.camera().eye())), 0, 1e-3);
  EXPECT_NEAR(Length(ToVec3d(scene.lights(0).area().edge_u()) - Vec3d{50, 0, 0}), 0, 1e-4);
}

}  // namespace
}  // namespace cinevol

// A client's own view math: see view_math.h.
#include "view_math.h"

#include <algorithm>
#include <cmath>

namespace cinevol {
namespace {

constexpr double kPi = 3.14159265358979323846;

double Radians(double degrees) { return degrees * kPi / 180; }
double Degrees(double radians) { return radians * 180 / kPi; }

// Rodrigues' rotation of v about the unit axis k by `degrees`.
Vec3d Rotate(Vec3d v, Vec3d k, double degrees) {
  const double a = Radians(degrees), c = std::cos(a), s = std::sin(a);
  return v * c + Cross(k, v) * s + k * (Dot(k, v) * (1 - c));
}

// The view's right and up as the screen shows them.
Vec3d Right(const ViewCamera& c) { return Normalized(Cross(c.target - c.eye, c.up)); }
Vec3d ScreenUp(const ViewCamera& c) { return Normalized(Cross(Right(c), c.target - c.eye)); }

}  // namespace

ViewCamera CameraOf(const v1::Camera& camera, const ViewCamera& fallback) {
  if (!camera.has_eye() || !camera.has_target()) return fallback;
  ViewCamera c;
  c.eye = ToVec3d(camera.eye());
  c.target = ToVec3d(camera.target());
  c.up = camera.has_up() ? ToVec3d(camera.up()) : Vec3d{0, 0, 1};
  c.fov_y_deg = camera.has_fov_y_deg() ? camera.fov_y_deg() : 30.0;
  if (!(Length(c.target - c.eye) > 0) || !(Length(Cross(c.target - c.eye, c.up)) > 0)) return fallback;
  return c;
}

v1::Camera ToProto(const ViewCamera& camera) {
  v1::Camera c;
  *c.mutable_eye() = ToProto(camera.eye);
  *c.mutable_target() = ToProto(camera.target);
  *c.mutable_up() = ToProto(camera.up);
  c.set_fov_y_deg(float(camera.fov_y_deg));
  return c;
}

double DragZoomFactor(double dy_px) { return std::exp(dy_px * 0.01); }

double WheelZoomFactor(double steps) { return std::pow(0.9, steps); }

void Orbit(ViewCamera& c, double yaw_deg, double pitch_deg) {
  const Vec3d right = Right(c), up = ScreenUp(c);
  Vec3d offset = Rotate(c.eye - c.target, up, -yaw_deg);
  const Vec3d turned_right = Rotate(right, up, -yaw_deg);
  offset = Rotate(offset, turned_right, -pitch_deg);
  c.eye = c.target + offset;
  c.up = Normalized(Cross(turned_right, c.target - c.eye));
}

void Zoom(ViewCamera& c, double factor) {
  if (!(factor > 0) || !std::isfinite(factor)) return;
  const Vec3d offset = c.eye - c.target;
  const double distance = Length(offset);
  c.eye = c.target + offset * (std::max(distance * factor, 1.0) / distance);
}

void Pan(ViewCamera& c, double dx, double dy, double viewport_height) {
  const double distance = Length(c.eye - c.target);
  const double mm_per_pixel = 2 * distance * std::tan(0.5 * Radians(c.fov_y_deg)) / std::max(1.0, viewport_height);
  const Vec3d shift = Right(c) * (-dx * mm_per_pixel) + ScreenUp(c) * (dy * mm_per_pixel);
  c.eye += shift;
  c.target += shift;
}

void OrbitLight(v1::AreaLight& light, const ViewCamera& c, double yaw_deg, double pitch_deg) {
  const Vec3d right = Right(c), up = ScreenUp(c);
  const auto turn = [&](Vec3d v) { return Rotate(Rotate(v, up, -yaw_deg), Rotate(right, up, -yaw_deg), -pitch_deg); };
  *light.mutable_center() = ToProto(c.target + turn(ToVec3d(light.center()) - c.target));
  *light.mutable_edge_u() = ToProto(turn(ToVec3d(light.edge_u())));
  *light.mutable_edge_v() = ToProto(turn(ToVec3d(light.edge_v())));
}

LightDirection DirectionOf(const v1::AreaLight& light, const ViewCamera& c) {
  const Vec3d right = Right(c), up = ScreenUp(c), to_eye = Normalized(c.eye - c.target);
  const Vec3d d = Normalized(ToVec3d(light.center()) - c.target);
  return {Degrees(std::atan2(Dot(d, right), Dot(d, to_eye))), Degrees(std::asin(std::clamp(Dot(d, up), -1.0, 1.0)))};
}

void SetDirection(v1::AreaLight& light, const ViewCamera& c, LightDirection direction) {
  const Vec3d right = Right(c), up = ScreenUp(c), to_eye = Normalized(c.eye - c.target);
  const Vec3d offset = ToVec3d(light.center()) - c.target;
  const double a = Radians(direction.azimuth_deg), e = Radians(direction.elevation_deg);
  const Vec3d from = Normalized(offset);
  const Vec3d to = (to_eye * std::cos(a) + right * std::sin(a)) * std::cos(e) + up * std::sin(e);
  // The rotation taking `from` to `to`, applied to the whole light.
  const Vec3d axis = Cross(from, to);
  const double s = Length(axis);
  if (!(s > 1e-6)) {
    *light.mutable_center() = ToProto(c.target + to * Length(offset));
    return;
  }
  const double degrees = Degrees(std::atan2(s, Dot(from, to)));
  const Vec3d k = axis / s;
  *light.mutable_center() = ToProto(c.target + Rotate(offset, k, degrees));
  *light.mutable_edge_u() = ToProto(Rotate(ToVec3d(light.edge_u()), k, degrees));
  *light.mutable_edge_v() = ToProto(Rotate(ToVec3d(light.edge_v()), k, degrees));
}

std::optional<ViewPoint> ProjectToView(const ViewCamera& camera, Vec3d point, double width, double height) {
  const Vec3d forward = Normalized(camera.target - camera.eye);
  const Vec3d right = Normalized(Cross(forward, camera.up)), up = Cross(right, forward);
  const Vec3d d = point - camera.eye;
  const double depth = Dot(d, forward);
  if (depth <= 1e-6) return std::nullopt;
  // Pixels per unit of tan(angle): the vertical field of view spans the height.
  const double scale = 0.5 * height / std::tan(0.5 * Radians(camera.fov_y_deg));
  return ViewPoint{0.5 * width + Dot(d, right) / depth * scale, 0.5 * height - Dot(d, up) / depth * scale};
}

std::vector<MarkerAxis> MarkerAxes(const ViewCamera& camera, const Placement& placement) {
  const Vec3d forward = Normalized(camera.target - camera.eye);
  const Vec3d right = Normalized(Cross(forward, camera.up)), up = Cross(right, forward);
  static constexpr struct {
    Vec3d lps;
    char plus, minus;
  } kAxes[] = {{{1, 0, 0}, 'L', 'R'}, {{0, 1, 0}, 'P', 'A'}, {{0, 0, 1}, 'S', 'I'}};
  std::vector<MarkerAxis> axes;
  for (const auto& axis : kAxes) {
    const Vec3d w = placement.DirectionToVolume(axis.lps);  // the camera lives in the volume-centred frame
    const MarkerAxis plus{axis.plus, Dot(w, right), Dot(w, up), -Dot(w, forward)};
    axes.push_back(plus);
    axes.push_back({axis.minus, -plus.x, -plus.y, -plus.depth});
  }
  std::stable_sort(axes.begin(), axes.end(), [](const MarkerAxis& a, const MarkerAxis& b) { return a.depth < b.depth; });
  return axes;
}

SliceGrid SliceGrid::Of(const v1::SliceImage& image) {
  return {ToVec3d(image.origin_mm()), ToVec3d(image.row_direction()), ToVec3d(image.column_direction()),
          image.row_spacing_mm(),     image.column_spacing_mm(),      int(image.width()),
          int(image.height())};
}

Vec3d SlicePixelToPatient(const SliceGrid& slice, double column, double row) {
  return slice.origin + slice.row * (column * slice.row_spacing) + slice.column * (row * slice.column_spacing);
}

SlicePixel PatientToSlicePixel(const SliceGrid& slice, Vec3d lps) {
  const Vec3d d = lps - slice.origin;
  return {Dot(d, slice.row) / slice.row_spacing, Dot(d, slice.column) / slice.column_spacing,
          Dot(d, Normalized(Cross(slice.row, slice.column)))};
}

double DistanceMm(Vec3d a, Vec3d b) { return Length(a - b); }

double AngleDeg(Vec3d a, Vec3d vertex, Vec3d b) {
  const double cosine = Dot(Normalized(a - vertex), Normalized(b - vertex));
  return Degrees(std::acos(std::clamp(cosine, -1.0, 1.0)));
}

}  // namespace cinevol

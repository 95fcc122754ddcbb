// Turntable camera and light motion.
#include "viewer/camera_control.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "scene/scene_builder.h"

namespace cinevol::viewer {
namespace {

Vec3f ToVec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

void Set(v1::Vec3* out, Vec3f v) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

// Rodrigues' rotation of v about the unit axis k by `degrees`.
Vec3f Rotate(Vec3f v, Vec3f k, float degrees) {
  const float a = degrees * kPi / 180.0f, c = std::cos(a), s = std::sin(a);
  return v * c + Cross(k, v) * s + k * (Dot(k, v) * (1 - c));
}

Vec3f Right(const ViewCamera& c) { return Normalize(Cross(c.target - c.eye, c.up)); }

}  // namespace

ViewCamera FromProto(const v1::Camera& camera, const ViewCamera& fallback) {
  if (!camera.has_eye() || !camera.has_target()) return fallback;
  ViewCamera c;
  c.eye = ToVec(camera.eye());
  c.target = ToVec(camera.target());
  c.up = camera.has_up() ? ToVec(camera.up()) : Vec3f{0, 0, 1};
  c.fov_y_deg = camera.has_fov_y_deg() ? camera.fov_y_deg() : 30.0f;
  if (!(Length(c.target - c.eye) > 0) || !(Length(Cross(c.target - c.eye, c.up)) > 0)) return fallback;
  return c;
}

v1::Camera ToProto(const ViewCamera& camera) {
  v1::Camera c;
  Set(c.mutable_eye(), camera.eye);
  Set(c.mutable_target(), camera.target);
  Set(c.mutable_up(), camera.up);
  c.set_fov_y_deg(camera.fov_y_deg);
  return c;
}

void Orbit(ViewCamera& c, float yaw_deg, float pitch_deg) {
  const Vec3f right = Right(c);
  const Vec3f up = Normalize(Cross(right, c.target - c.eye));
  Vec3f offset = c.eye - c.target;
  offset = Rotate(offset, up, -yaw_deg);
  const Vec3f turned_right = Rotate(right, up, -yaw_deg);
  offset = Rotate(offset, turned_right, -pitch_deg);
  c.eye = c.target + offset;
  c.up = Normalize(Cross(turned_right, c.target - c.eye));
}

void Zoom(ViewCamera& c, float factor) {
  const Vec3f offset = c.eye - c.target;
  const float distance = Length(offset);
  c.eye = c.target + offset * (std::max(distance * factor, 1.0f) / distance);
}

void Pan(ViewCamera& c, float dx, float dy, int viewport_height) {
  const float distance = Length(c.eye - c.target);
  const float mm_per_pixel =
      2.0f * distance * std::tan(0.5f * c.fov_y_deg * kPi / 180.0f) / float(std::max(1, viewport_height));
  const Vec3f right = Right(c), up = Normalize(Cross(right, c.target - c.eye));
  const Vec3f shift = right * (-dx * mm_per_pixel) + up * (dy * mm_per_pixel);
  c.eye += shift;
  c.target += shift;
}

ViewCamera NamedView(const ViewCamera& c, v1::NamedView view,
                     const google::protobuf::RepeatedField<double>& direction) {
  DirectionCosines d{1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (direction.size() == 9) std::copy(direction.begin(), direction.end(), d.begin());
  const ViewDirections v = NamedViewDirections(view, d);
  ViewCamera out = c;
  out.eye = c.target + v.to_eye * Length(c.eye - c.target);
  out.up = v.up;
  return out;
}

void OrbitLight(v1::AreaLight& light, const ViewCamera& c, float yaw_deg, float pitch_deg) {
  const Vec3f right = Right(c), up = Normalize(Cross(right, c.target - c.eye));
  auto turn = [&](Vec3f v) { return Rotate(Rotate(v, up, -yaw_deg), Rotate(right, up, -yaw_deg), -pitch_deg); };
  Set(light.mutable_center(), c.target + turn(ToVec(light.center()) - c.target));
  Set(light.mutable_edge_u(), turn(ToVec(light.edge_u())));
  Set(light.mutable_edge_v(), turn(ToVec(light.edge_v())));
}

LightDirection DirectionOf(const v1::AreaLight& light, const ViewCamera& c) {
  const Vec3f right = Right(c), up = Normalize(Cross(right, c.target - c.eye)), to_eye = Normalize(c.eye - c.target);
  const Vec3f d = Normalize(ToVec(light.center()) - c.target);
  return {std::atan2(Dot(d, right), Dot(d, to_eye)) * 180.0f / kPi,
          std::asin(std::clamp(Dot(d, up), -1.0f, 1.0f)) * 180.0f / kPi};
}

void SetDirection(v1::AreaLight& light, const ViewCamera& c, LightDirection direction) {
  const Vec3f right = Right(c), up = Normalize(Cross(right, c.target - c.eye)), to_eye = Normalize(c.eye - c.target);
  const Vec3f offset = ToVec(light.center()) - c.target;
  const float a = direction.azimuth_deg * kPi / 180.0f, e = direction.elevation_deg * kPi / 180.0f;
  const Vec3f from = Normalize(offset);
  const Vec3f to = (to_eye * std::cos(a) + right * std::sin(a)) * std::cos(e) + up * std::sin(e);
  // The rotation taking `from` to `to`, applied to the whole light.
  const Vec3f axis = Cross(from, to);
  const float s = Length(axis);
  if (!(s > 1e-6f)) {
    Set(light.mutable_center(), c.target + to * Length(offset));
    return;
  }
  const float degrees = std::atan2(s, Dot(from, to)) * 180.0f / kPi;
  const Vec3f k = axis / s;
  Set(light.mutable_center(), c.target + Rotate(offset, k, degrees));
  Set(light.mutable_edge_u(), Rotate(ToVec(light.edge_u()), k, degrees));
  Set(light.mutable_edge_v(), Rotate(ToVec(light.edge_v()), k, degrees));
}

}  // namespace cinevol::viewer

// Every position and direction a scene's camera and lights hold: what moves
// between a scene's two frames (Scene.frame), on the server
// (server/scene/scene_frame.cpp) and in the client library
// (client-cpp/library/placement.cpp). A field the scene model adds that holds
// a position or a direction belongs here.
#pragma once

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

// Calls point(v1::Vec3*) on each position and direction(v1::Vec3*) on each
// direction that is set; unset fields stay unset.
template <class OnPoint, class OnDirection>
void ForEachCameraAndLightVector(v1::Scene& scene, OnPoint&& point, OnDirection&& direction) {
  v1::Camera& camera = *scene.mutable_camera();
  if (camera.has_eye()) point(camera.mutable_eye());
  if (camera.has_target()) point(camera.mutable_target());
  if (camera.has_up()) direction(camera.mutable_up());
  for (v1::Light& light : *scene.mutable_lights()) {
    if (light.has_area()) {
      point(light.mutable_area()->mutable_center());
      direction(light.mutable_area()->mutable_edge_u());
      direction(light.mutable_area()->mutable_edge_v());
    } else if (light.has_point()) {
      point(light.mutable_point()->mutable_position());
    } else if (light.has_directional()) {
      direction(light.mutable_directional()->mutable_direction());
    } else if (light.has_environment() && light.environment().has_gradient() &&
               light.environment().gradient().has_up()) {
      direction(light.mutable_environment()->mutable_gradient()->mutable_up());
    }
  }
}

}  // namespace cinevol

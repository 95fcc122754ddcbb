#include "session_state.h"

namespace cinevol {

SessionState::SessionState(const v1::CreateSessionRequest& request, const v1::CreateSessionResponse& created)
    : request_(request) {
  *request_.mutable_scene() = created.scene();
  request_.mutable_scene()->clear_volume();  // volume_id says which
}

void SessionState::Apply(const v1::SessionEvent& event) {
  v1::Scene& scene = *request_.mutable_scene();
  switch (event.kind_case()) {
    case v1::SessionEvent::kCamera:
      *scene.mutable_camera() = event.camera();
      break;
    case v1::SessionEvent::kLights:
      *scene.mutable_lights() = event.lights().lights();
      break;
    case v1::SessionEvent::kTransferFunction:
      *scene.mutable_transfer_function() = event.transfer_function();
      break;
    case v1::SessionEvent::kRender: {
      // Set fields change (a seed of 0 and an unspecified reconstruction are
      // unset); a render event never resizes.
      v1::RenderSettings edit = event.render();
      edit.clear_width();
      edit.clear_height();
      scene.mutable_render()->MergeFrom(edit);
      break;
    }
    case v1::SessionEvent::kStream:
      request_.mutable_stream()->MergeFrom(event.stream());  // set fields change, as on the server
      break;
    case v1::SessionEvent::kResize:
      *request_.mutable_viewport() = event.resize();
      scene.mutable_render()->set_width(event.resize().width());
      scene.mutable_render()->set_height(event.resize().height());
      break;
    case v1::SessionEvent::kClipping:
      *scene.mutable_clipping() = event.clipping();
      break;
    case v1::SessionEvent::kLabels:
      *scene.mutable_labels() = event.labels();
      break;
    case v1::SessionEvent::kPause:
      paused_ = true;
      break;
    case v1::SessionEvent::kResume:
      paused_ = false;
      break;
    case v1::SessionEvent::KIND_NOT_SET:
      break;
  }
}

}  // namespace cinevol

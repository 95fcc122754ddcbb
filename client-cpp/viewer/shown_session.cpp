// The state shown: the server's, with this viewer's unanswered edits over it.
#include "viewer/shown_session.h"

#include <algorithm>

namespace cinevol::viewer {
namespace {

constexpr int kCamera = v1::SessionEvent::kCamera, kTransferFunction = v1::SessionEvent::kTransferFunction,
              kMeasurements = v1::SessionEvent::kMeasurements;

// The kinds an edit lays over the shown state; others (a resize, a pause, a
// pointer) only go to the session.
bool Shows(int kind) {
  switch (kind) {
    case v1::SessionEvent::kCamera:
    case v1::SessionEvent::kLights:
    case v1::SessionEvent::kTransferFunction:
    case v1::SessionEvent::kRender:
    case v1::SessionEvent::kStream:
    case v1::SessionEvent::kClipping:
    case v1::SessionEvent::kLabels:
    case v1::SessionEvent::kMeasurements:
    case v1::SessionEvent::kTime:
    case v1::SessionEvent::kFusion:
      return true;
    default:
      return false;
  }
}

// Asks the server to work something out: a named view's numbers, a preset's points.
bool AsksTheServer(const v1::SessionEvent& e) {
  return (e.has_camera() && e.camera().view() != v1::NAMED_VIEW_UNSPECIFIED) ||
         (e.has_transfer_function() && e.transfer_function().points().empty());
}

}  // namespace

void ShownSession::Start(v1::SessionState first) {
  started_ = true;
  server_ = std::move(first);
  edits_.clear();
  Show();
}

void ShownSession::Clear() {
  started_ = false;
  server_.Clear();
  edits_.clear();
  Show();
}

void ShownSession::Adopt(v1::SessionState newest) {
  server_ = std::move(newest);
  Settle();
  Show();
}

bool ShownSession::Answered(int kind, const Edit& edit) const {
  if (edit.ticket == 0) return false;  // not posted yet
  const Delivery d = sink_.DeliveryOf(edit.ticket);
  if (d.state == Delivery::kDropped) return true;  // it will never be answered: the server's state stands
  if (d.state == Delivery::kWaiting) return false;
  // Measurements change no picture, so the session numbers no state after
  // them: the state holds them once it holds what was sent (or a later event).
  if (kind == kMeasurements) {
    const auto& sent = edit.event.measurements().measurements();
    const auto& held = server_.scene().measurements();
    if (sent.size() == held.size() &&
        std::equal(sent.begin(), sent.end(), held.begin(),
                   [](const auto& a, const auto& b) { return a.SerializeAsString() == b.SerializeAsString(); })) {
      return true;
    }
  }
  return d.seq <= server_.last_event_seq();
}

void ShownSession::Settle() {
  const std::size_t before = edits_.size();
  std::erase_if(edits_, [&](const auto& kind_edit) { return Answered(kind_edit.first, kind_edit.second); });
  if (edits_.size() != before) Show();
}

void ShownSession::Show() {
  shown_ = server_;
  v1::Scene& scene = *shown_.mutable_scene();
  for (const auto& [kind, edit] : edits_) {
    const v1::SessionEvent& e = edit.event;
    if (AsksTheServer(e)) continue;  // the server's numbers show once they come
    switch (e.kind_case()) {
      case v1::SessionEvent::kCamera:
        *scene.mutable_camera() = e.camera();
        break;
      case v1::SessionEvent::kLights:
        *scene.mutable_lights() = e.lights().lights();
        break;
      case v1::SessionEvent::kTransferFunction:
        *scene.mutable_transfer_function() = e.transfer_function();
        break;
      case v1::SessionEvent::kRender:
        scene.mutable_render()->MergeFrom(e.render());
        break;
      case v1::SessionEvent::kStream:
        shown_.mutable_stream()->MergeFrom(e.stream());
        break;
      case v1::SessionEvent::kClipping:
        *scene.mutable_clipping() = e.clipping();
        break;
      case v1::SessionEvent::kLabels:
        *scene.mutable_labels() = e.labels();
        break;
      case v1::SessionEvent::kMeasurements:
        *scene.mutable_measurements() = e.measurements().measurements();
        break;
      case v1::SessionEvent::kTime:
        *scene.mutable_time() = e.time();
        break;
      case v1::SessionEvent::kFusion:  // an empty volume id removes the second volume
        if (e.fusion().volume_id().empty()) {
          scene.clear_fusion();
        } else {
          *scene.mutable_fusion() = e.fusion();
        }
        break;
      default:
        break;
    }
  }
  camera_ = CameraOf(scene.camera(), camera_);
}

bool ShownSession::Resolving() const {
  return std::any_of(edits_.begin(), edits_.end(), [](const auto& kind_edit) { return AsksTheServer(kind_edit.second.event); });
}

std::string ShownSession::ResolvingPreset() const {
  const auto it = edits_.find(kTransferFunction);
  return it != edits_.end() && AsksTheServer(it->second.event) ? it->second.event.transfer_function().preset() : "";
}

void ShownSession::Record(v1::SessionEvent event, bool post_now) {
  if (!sink_.Drives()) return;  // another drives: what shows is theirs
  const int kind = event.kind_case();
  if (!Shows(kind)) {
    sink_.Post(std::move(event));
    return;
  }
  Edit& edit = edits_[kind];
  edit.event = std::move(event);
  edit.ticket = post_now ? sink_.Post(edit.event) : 0;
  Show();
}

void ShownSession::SetCamera(const ViewCamera& camera) {
  v1::SessionEvent e;
  *e.mutable_camera() = ToProto(camera);
  Record(std::move(e), false);
}

void ShownSession::TurnTo(v1::NamedView view) {
  v1::SessionEvent e;
  v1::Camera& c = *e.mutable_camera();
  c = ToProto(camera_);  // eye and target say where to turn about and how far
  c.set_view(view);
  c.clear_up();          // the view's own
  Record(std::move(e), true);
}

void ShownSession::SetTransferFunction(const v1::TransferFunction& tf) {
  v1::SessionEvent e;
  *e.mutable_transfer_function() = tf;
  Record(std::move(e), true);
}

void ShownSession::ChoosePreset(const std::string& name) {
  v1::SessionEvent e;
  e.mutable_transfer_function()->set_preset(name);  // no points: the server expands it for this volume
  Record(std::move(e), true);
}

void ShownSession::SetLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights) {
  v1::SessionEvent e;
  *e.mutable_lights()->mutable_lights() = lights;
  Record(std::move(e), true);
}

void ShownSession::SetRender(const v1::RenderSettings& render) {
  v1::SessionEvent e;
  *e.mutable_render() = render;
  Record(std::move(e), true);
}

void ShownSession::SetStream(const v1::StreamSettings& stream) {
  v1::SessionEvent e;
  *e.mutable_stream() = stream;
  Record(std::move(e), true);
}

void ShownSession::SetClipping(const v1::Clipping& clipping) {
  v1::SessionEvent e;
  *e.mutable_clipping() = clipping;
  Record(std::move(e), true);
}

void ShownSession::SetLabels(const v1::Labels& labels) {
  v1::SessionEvent e;
  *e.mutable_labels() = labels;
  Record(std::move(e), true);
}

void ShownSession::SetMeasurements(const std::vector<v1::Measurement>& measurements) {
  v1::SessionEvent e;
  v1::MeasurementList& list = *e.mutable_measurements();  // set even when empty: the last one deleted
  for (const v1::Measurement& m : measurements) *list.add_measurements() = m;
  Record(std::move(e), true);
}

void ShownSession::SetTime(const v1::Time& time) {
  v1::SessionEvent e;
  *e.mutable_time() = time;
  Record(std::move(e), true);
}

void ShownSession::SetFusion(const v1::Fusion& fusion) {
  v1::SessionEvent e;
  *e.mutable_fusion() = fusion;
  Record(std::move(e), true);
}

void ShownSession::Send(v1::SessionEvent event) {
  // Render and stream settings merge into what waits, as the server merges them.
  const int kind = event.kind_case();
  if ((event.has_render() || event.has_stream()) && edits_.count(kind)) {
    v1::SessionEvent merged = edits_[kind].event;
    merged.MergeFrom(event);
    event = std::move(merged);
  }
  Record(std::move(event), true);
}

bool ShownSession::Flush() {
  const auto it = edits_.find(kCamera);
  if (it == edits_.end() || it->second.ticket != 0) return false;
  if (!sink_.Drives()) {  // the role went elsewhere since: nothing to send it to
    edits_.erase(it);
    Show();
    return false;
  }
  it->second.ticket = sink_.Post(it->second.event);
  return true;
}

bool ShownSession::camera_waiting() const {
  const auto it = edits_.find(kCamera);
  return it != edits_.end() && it->second.ticket == 0;
}

}  // namespace cinevol::viewer

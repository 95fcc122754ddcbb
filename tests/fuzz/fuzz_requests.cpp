// Session requests as the service checks them: the first byte picks the
// message, the rest is its protobuf wire form (unparsable input is skipped).
//   0: CreateSessionRequest -> InitialScene (+ MergeStreamSettings of its stream)
//   1: SessionEvent         -> ApplyEvent on a session's scene
//   2: SnapshotRequest      -> SnapshotSpp for the session's viewport
//   3: StreamSettings       -> MergeStreamSettings
// against a default SessionLimits, a 16^3 head phantom and a VolumeRegistry
// with no data roots. InputError, RpcError (std::exceptions) are the expected
// refusals; crashes, sanitizer reports and an accepted scene that fails
// validation are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <memory>

#include "cinevol/v1/service.pb.h"
#include "io/phantom.h"
#include "io/scene_file.h"
#include "service/session_requests.h"
#include "service/volume_registry.h"

namespace cv = cinevol;
namespace v1 = cinevol::v1;
using cinevol::service::SessionLimits;

namespace {

cv::Volume SmallHead() {
  v1::Phantom head;
  head.set_kind(v1::Phantom::HEAD);
  head.set_size(16);
  return cv::MakePhantom(head);
}

struct World {
  SessionLimits limits;
  cv::Volume volume = SmallHead();
  cv::service::VolumeRegistry registry{{}, {}};
  v1::Scene session_scene;  // a session's scene: preset ct-bone at 64x48
  cv::FrameSettings settings;
};

World* world;

v1::Scene MakeSessionScene(const World& w) {
  v1::CreateSessionRequest create;
  create.mutable_viewport()->set_width(64);
  create.mutable_viewport()->set_height(48);
  create.set_preset("ct-bone");
  return cv::service::InitialScene(create, w.volume, w.limits, w.registry);
}

// What the service relies on after a request was accepted.
void CheckAccepted(const v1::Scene& scene, const SessionLimits& limits) {
  if (!cv::ValidateSceneParts(scene).empty()) std::abort();
  const auto& r = scene.render();
  if (r.width() < 1 || r.height() < 1 || std::uint64_t(r.width()) * r.height() > limits.max_pixels) std::abort();
  if (int(r.spp()) > limits.max_frame_spp || int(r.max_bounces()) > limits.max_bounces) std::abort();
  if (scene.lights_size() > limits.max_lights) std::abort();
  if (scene.transfer_function().points_size() > limits.max_tf_points) std::abort();
}

void CheckSettings(const cv::FrameSettings& s) {
  if (s.jpeg_quality < 1 || s.jpeg_quality > 100 || s.final_jpeg_quality < 1 || s.final_jpeg_quality > 100 ||
      s.target_spp < 1) {
    std::abort();
  }
}

void Event(const v1::SessionEvent& event) {
  v1::Scene scene = world->session_scene;
  cv::FrameSettings settings = world->settings;
  try {
    cv::service::ApplyEvent(event, scene, settings, world->limits, world->registry);
  } catch (const std::exception&) {
    return;
  }
  CheckAccepted(scene, world->limits);
  CheckSettings(settings);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  world = new World;
  world->session_scene = MakeSessionScene(*world);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1 << 16)) return 0;
  const int kind = data[0] % 4;
  const std::uint8_t* wire = data + 1;
  const int wire_size = int(size - 1);
  switch (kind) {
    case 0: {
      v1::CreateSessionRequest request;
      if (!request.ParseFromArray(wire, wire_size)) return 0;
      v1::Scene scene;
      try {
        scene = cv::service::InitialScene(request, world->volume, world->limits, world->registry);
      } catch (const std::exception&) {
        return 0;
      }
      CheckAccepted(scene, world->limits);
      try {
        CheckSettings(cv::service::MergeStreamSettings({}, request.stream(), "stream"));
      } catch (const std::exception&) {
      }
      break;
    }
    case 1: {
      v1::SessionEvent event;
      if (!event.ParseFromArray(wire, wire_size)) return 0;
      Event(event);
      break;
    }
    case 2: {
      v1::SnapshotRequest request;
      if (!request.ParseFromArray(wire, wire_size)) return 0;
      const auto& r = world->session_scene.render();
      try {
        const int spp = cv::service::SnapshotSpp(request, std::uint64_t(r.width()) * r.height(), world->limits);
        if (spp < 1 || spp > world->limits.max_snapshot_spp) std::abort();
      } catch (const std::exception&) {
      }
      break;
    }
    case 3: {
      v1::StreamSettings edit;
      if (!edit.ParseFromArray(wire, wire_size)) return 0;
      try {
        CheckSettings(cv::service::MergeStreamSettings(world->settings, edit, "stream"));
      } catch (const std::exception&) {
      }
      break;
    }
  }
  return 0;
}

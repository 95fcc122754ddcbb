// Session requests as the service checks them: the first byte picks the
// message, the rest is its protobuf wire form (unparsable input is skipped).
//   0: CreateSessionRequest -> InitialState (and its stream's frame settings)
//   1: SessionEvent         -> ApplyEvent on a session's state
//   2: SnapshotRequest      -> SnapshotSpp for the session's viewport
//   3: StreamSettings       -> a stream event's check and its frame settings
// against a default SessionLimits, a 16^3 head phantom and a VolumeRegistry
// with no data roots (environment maps are refused, as on such a server). InputError, RpcError (std::exceptions) are
// the expected refusals; crashes, sanitizer reports and an accepted scene that fails validation are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <memory>

#include "cinevol/v1/service.pb.h"
#include "io/phantom.h"
#include "scene/scene_file.h"
#include "scene/session_state.h"
#include "runtime/volume_registry.h"

namespace cv = cinevol;
namespace v1 = cinevol::v1;
using cinevol::SessionLimits;

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
  cv::MapResolver resolve_map = [this](const std::string& map, const std::string& field) {
    return registry.ResolveDataPath(map, field).string();
  };
  v1::SessionState session;  // a session's state: preset ct-bone at 64x48
};

World* world;

v1::SessionState MakeSession(const World& w) {
  v1::CreateSessionRequest create;
  create.mutable_viewport()->set_width(64);
  create.mutable_viewport()->set_height(48);
  create.set_preset("ct-bone");
  return cv::InitialState(create, w.volume, w.limits, w.resolve_map);
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

void CheckSettings(const v1::StreamSettings& s) {
  auto outside = [](bool has, std::uint32_t v, std::uint32_t lo, std::uint32_t hi) {
    return has && (v < lo || v > hi);
  };
  if (outside(s.has_jpeg_quality(), s.jpeg_quality(), 1, 100) ||
      outside(s.has_final_jpeg_quality(), s.final_jpeg_quality(), 1, 100) ||
      outside(s.has_target_spp(), s.target_spp(), 1, 65536) || !v1::Denoiser_IsValid(s.denoiser())) {
    std::abort();
  }
}

void CheckState(const v1::SessionState& state, const SessionLimits& limits) {
  CheckAccepted(state.scene(), limits);
  CheckSettings(state.stream());
  if (state.viewport().width() != state.scene().render().width()) std::abort();
}

void Event(const v1::SessionEvent& event) {
  v1::SessionState state = world->session;
  try {
    cv::ApplyEvent(state, event, &world->limits, world->resolve_map);
  } catch (const std::exception&) {
    return;
  }
  CheckState(state, world->limits);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  world = new World;
  world->session = MakeSession(*world);
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
      v1::SessionState state;
      try {
        state = cv::InitialState(request, world->volume, world->limits, world->resolve_map);
      } catch (const std::exception&) {
        return 0;
      }
      CheckState(state, world->limits);
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
      const auto& r = world->session.scene().render();
      try {
        const int spp = cv::SnapshotSpp(request, std::uint64_t(r.width()) * r.height(), world->limits);
        if (spp < 1 || spp > world->limits.max_snapshot_spp) std::abort();
      } catch (const std::exception&) {
      }
      break;
    }
    case 3: {
      v1::SessionEvent event;
      if (!event.mutable_stream()->ParseFromArray(wire, wire_size)) return 0;
      Event(event);
      break;
    }
  }
  return 0;
}

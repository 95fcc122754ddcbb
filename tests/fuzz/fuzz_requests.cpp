// Session requests as the service checks them: the first byte picks the
// message, the rest is its protobuf wire form (unparsable input is skipped).
//   0: CreateSessionRequest -> InitialState (and its stream's frame settings)
//   1: SessionEvent         -> ApplyEvent on a session's state
//   2: SnapshotRequest      -> SnapshotSpp for the session's viewport
//   3: StreamSettings       -> a stream event's check and its frame settings
//   4: a volume's geometry, then a SliceRequest -> what the server does with
//      both: the geometry check (dimensions to 2^32, any spacing), then on a
//      small volume of that spacing the CT table search, a new session's
//      framing and the slice's plan (and render, where it is small)
//   5: a frame number byte, then an instance's WADO-RS metadata (DICOM JSON)
//      -> where that frame lies (FramePlaneOf) and its rendered frame from the
//      head (FrameOf: its own grid where small, else fitted in a viewport)
// against a default SessionLimits, a 16^3 head phantom and a VolumeRegistry
// with no data roots (environment maps are refused, as on such a server). InputError, RpcError (std::exceptions) are
// the expected refusals; crashes, sanitizer reports, an accepted scene that fails validation and a slice past its
// bounds are bugs.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <optional>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "io/phantom.h"
#include "io/table_finder.h"
#include "pacs/dicom_json.h"
#include "pacs/frame_plane.h"
#include "reading/slice.h"
#include "runtime/reading_calls.h"
#include "runtime/volume_registry.h"
#include "scene/scene_file.h"
#include "scene/session_state.h"

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
  return cv::InitialState(create, {w.volume, nullptr, "head", w.resolve_map}, w.limits);
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
    cv::ApplyEvent(state, event, {world->volume, nullptr, "head", world->resolve_map}, &world->limits);
  } catch (const std::exception&) {
    return;
  }
  CheckState(state, world->limits);
}

// Kind 4's input: the dimensions (a small volume is made of the first
// dimension's low bits, as the fuzzer cannot allocate 2^31 voxels) and the
// spacing as they came, then the slice request's wire form.
struct Geometry {
  std::uint32_t dims[3];
  float spacing[3];
};

void Geometric(const std::uint8_t* data, std::size_t size) {
  Geometry g;
  if (size < sizeof g) return;
  std::memcpy(&g, data, sizeof g);
  const cv::Vec3f spacing{g.spacing[0], g.spacing[1], g.spacing[2]};
  try {
    cv::CheckVolumeGeometry(
        {int(std::min<std::uint32_t>(g.dims[0], INT32_MAX)), int(std::min<std::uint32_t>(g.dims[1], INT32_MAX)),
         int(std::min<std::uint32_t>(g.dims[2], INT32_MAX))},
        spacing, "fuzz");
  } catch (const std::exception&) {
  }
  v1::SliceRequest request;
  if (!request.ParseFromArray(data + sizeof g, int(size - sizeof g))) return;
  const cv::Vec3i small{1 + int(g.dims[0] % 12), 1 + int(g.dims[1] % 12), 1 + int(g.dims[2] % 12)};
  std::vector<float> values(std::size_t(small.x) * small.y * small.z);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = float(int(i * 37 % 2000) - 1000);  // air to bone, HU
  cv::VolumeMetadata meta;
  meta.modality = "CT";
  meta.value_unit = "HU";
  std::optional<cv::Volume> volume;
  try {
    volume.emplace(small, spacing, std::move(values), meta);
  } catch (const std::exception&) {
    return;  // the geometry check refused it
  }
  cv::FindTable(*volume);
  v1::CreateSessionRequest create;
  create.mutable_viewport()->set_width(32);
  create.mutable_viewport()->set_height(24);
  try {
    CheckState(cv::InitialState(create, {*volume, nullptr, "geometry", world->resolve_map}, world->limits),
               world->limits);
  } catch (const std::exception&) {
  }
  try {
    const cv::SliceSpec spec = cv::service::SliceSpecOf(request, *volume);
    const cv::SliceGeometry plan = cv::PlanSlice(*volume, spec);
    const long long pixels = static_cast<long long>(plan.width) * plan.height;
    if (plan.width < 1 || plan.height < 1 || std::max(plan.width, plan.height) > cv::kMaxSliceSide) std::abort();
    if (plan.slab_half < 0 || pixels * (2LL * plan.slab_half + 1) > cv::kMaxSliceSamples) std::abort();
    if (!cv::IsFinite(plan.top_left_lps) || !(plan.pixel_width_mm > 0) || !(plan.pixel_height_mm > 0)) std::abort();
    if (pixels * (2LL * plan.slab_half + 1) <= (1 << 16)) cv::RenderSlice(*volume, {}, nullptr, spec);
  } catch (const std::exception&) {
  }
}

// Kind 5: hostile metadata places a frame or is refused; a placed frame renders within a slice's bounds.
void Frame(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return;
  cv::pacs::JsonDocument storage;
  cv::pacs::FramePlane plane;
  try {
    const auto datasets =
        cv::pacs::ParseDicomJson(std::string_view(reinterpret_cast<const char*>(data + 1), size - 1), storage);
    if (datasets.empty()) return;
    plane = cv::pacs::FramePlaneOf(datasets.front(), data[0]);
  } catch (const std::exception&) {
    return;
  }
  v1::RenderFrameRequest request;
  if (std::int64_t(plane.rows) * plane.columns > (1 << 14)) {
    request.mutable_viewport()->set_width(1 + data[0] % 64);
    request.mutable_viewport()->set_height(1 + data[0] / 4 % 64);
  }
  try {
    const v1::SliceImage image = cv::service::FrameOf(request, plane, world->volume);
    if (image.width() < 1 || image.height() < 1 || std::max(image.width(), image.height()) > cv::kMaxSliceSide) {
      std::abort();
    }
  } catch (const std::exception&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  world = new World;
  world->session = MakeSession(*world);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1 << 16)) return 0;
  const int kind = data[0] % 6;
  const std::uint8_t* wire = data + 1;
  const int wire_size = int(size - 1);
  switch (kind) {
    case 0: {
      v1::CreateSessionRequest request;
      if (!request.ParseFromArray(wire, wire_size)) return 0;
      v1::SessionState state;
      try {
        state = cv::InitialState(request, {world->volume, nullptr, "head", world->resolve_map}, world->limits);
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
    case 4:
      Geometric(wire, std::size_t(wire_size));
      break;
    case 5:
      Frame(wire, std::size_t(wire_size));
      break;
  }
  return 0;
}

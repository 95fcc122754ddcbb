// cinevol-bench events: what a camera event costs the server before any
// frame renders (docs/architecture.md, "A camera event"), per step:
//   rule      scene/session_state.h's ApplyEvent with the server's default limits:
//             the camera edited in place, only the camera and frame checked
//   old rule  what the server did before issue 33, re-enacted with today's
//             functions: the whole scene copied, every part defaulted and validated
//   state     the session's state serialised: the message the stream sends before the frame
//   update    FramePipeline::Update with kCameraChanged: the camera resolved, nothing rebuilt
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bench.h"
#include "pipeline/frame_pipeline.h"
#include "scene/session_state.h"

namespace cinevol::bench {
namespace {

using Clock = std::chrono::steady_clock;

struct Stats {
  std::vector<double> us;
  void Add(Clock::time_point start) {
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
  }
  double Percentile(double p) {
    std::sort(us.begin(), us.end());
    return us.empty() ? 0 : us[std::min(us.size() - 1, std::size_t(p * double(us.size())))];
  }
};

v1::SessionEvent CameraAt(int i, const v1::Camera& from) {
  const float angle = 0.01f * float(i);
  v1::SessionEvent e;
  e.set_seq(std::uint64_t(i) + 1);
  v1::Camera& c = *e.mutable_camera();
  c.mutable_eye()->set_x(from.eye().x() * std::cos(angle) - from.eye().y() * std::sin(angle));
  c.mutable_eye()->set_y(from.eye().x() * std::sin(angle) + from.eye().y() * std::cos(angle));
  c.mutable_eye()->set_z(from.eye().z());
  *c.mutable_target() = from.target();
  *c.mutable_up() = from.up();
  c.set_fov_y_deg(from.fov_y_deg());
  return e;
}

}  // namespace

int RunEventBench(const EventBenchOptions& o) {
  const LoadedScene loaded = LoadScene(o);
  v1::CreateSessionRequest request;
  *request.mutable_scene() = loaded.scene;
  request.mutable_viewport()->set_width(o.width > 0 ? o.width : 1280);
  request.mutable_viewport()->set_height(o.height > 0 ? o.height : 720);
  const SessionLimits limits;
  const SceneContext context{*loaded.volume, loaded.labels.get()};
  v1::SessionState state = InitialState(request, context, limits);
  const v1::Camera start = state.scene().camera();  // numbers: events carry eye and target, as a viewer's do

  FramePipeline pipeline(Backend::kCpu, loaded.volume, {}, loaded.labels);
  pipeline.Update(state.scene(), SessionFrameSettings(Backend::kCpu));
  Stats rule, old_rule, message, update;
  std::string bytes;
  for (int i = 0; i < o.events; ++i) {
    const v1::SessionEvent event = CameraAt(i, start);
    auto t = Clock::now();
    const unsigned changes = ApplyEvent(state, event, context, &limits);
    rule.Add(t);

    t = Clock::now();
    v1::Scene copy = state.scene();
    *copy.mutable_camera() = event.camera();
    ApplyDefaults(copy);
    if (!ValidateSceneParts(copy).empty()) throw std::runtime_error("the old rule refused an orbit event");
    old_rule.Add(t);

    t = Clock::now();
    state.SerializeToString(&bytes);
    message.Add(t);

    t = Clock::now();
    pipeline.Update(state.scene(), SessionFrameSettings(Backend::kCpu), changes);
    update.Add(t);
  }
  std::string table = fmt::format(
      "\n`{}`\n\n{} camera events on {} ({} lights, {} transfer-function points), state message {} bytes\n\n"
      "| step | median us | p95 us |\n|---|---|---|\n",
      o.command_line, o.events, o.volume.empty() ? o.scene : o.volume,
      state.scene().lights_size(), state.scene().transfer_function().points_size(), bytes.size());
  for (auto [name, stats] :
       {std::pair{"ApplyEvent (the rule)", &rule}, std::pair{"the old rule, re-enacted", &old_rule},
        std::pair{"state message serialised", &message}, std::pair{"FramePipeline::Update (camera)", &update}}) {
    table += fmt::format("| {} | {:.1f} | {:.1f} |\n", name, stats->Percentile(0.5), stats->Percentile(0.95));
  }
  Report(o, table);
  return 0;
}

}  // namespace cinevol::bench

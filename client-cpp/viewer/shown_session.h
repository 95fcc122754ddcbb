// The session as the viewer shows it: the server's newest state (resolved:
// the camera as numbers, the transfer function as points), with the edits
// this viewer sent that the server has not answered yet laid over it, so
// that a drag goes on from where the mouse left the camera rather than from
// where the server had it a round trip ago. An edit is dropped once a state
// answers it (or once it can no longer reach the server): what shows then is
// the server's. The viewer works nothing out of its own: a preset or a named
// view goes as asked, and shows once the server's numbers come back.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "view_math.h"

namespace cinevol::viewer {

// Where an event this viewer posted stands.
struct Delivery {
  enum State { kWaiting, kSent, kDropped };  // dropped: superseded, refused, or its stream ended
  State state = kWaiting;
  std::uint64_t seq = 0;  // kSent: the number a state's last_event_seq reaches once it is applied
};

// Where edits go: the session link (connection.h), or a test's record.
class EventSink {
 public:
  virtual ~EventSink() = default;
  virtual bool Drives() const = 0;                          // this viewer's edits go to the session now
  virtual std::uint64_t Post(v1::SessionEvent event) = 0;  // returns a ticket (> 0)
  virtual Delivery DeliveryOf(std::uint64_t ticket) const = 0;
};

class ShownSession {
 public:
  explicit ShownSession(EventSink& sink) : sink_(sink) {}

  // A new session: its first state, no edits pending.
  void Start(v1::SessionState first);
  // No session: nothing shown until the next starts.
  void Clear();
  // The server's newest state.
  void Adopt(v1::SessionState newest);
  // Drops the edits the server has answered, or that will never reach it.
  void Settle();

  bool started() const { return started_; }
  const v1::SessionState& state() const { return shown_; }  // what to show
  const v1::Scene& scene() const { return shown_.scene(); }
  const v1::SessionState& server() const { return server_; }  // the server's newest, without edits
  // The camera shown, as numbers (the last ones shown while a named view waits for the server's).
  ViewCamera camera() const { return camera_; }
  // A named view or a preset waits for the server's numbers; the preset's
  // name while one does ("" otherwise).
  bool Resolving() const;
  std::string ResolvingPreset() const;
  bool Pending() const { return !edits_.empty(); }  // an edit not yet answered

  // Edits: each shows at once and goes to the session; none while this
  // viewer does not drive it.
  void SetCamera(const ViewCamera& camera);  // goes with the next Flush: one camera event per displayed frame
  void TurnTo(v1::NamedView view);           // about the target at the current distance: the server turns it
  void SetTransferFunction(const v1::TransferFunction& tf);
  void ChoosePreset(const std::string& name);  // the server fits it to the volume's values and spacing
  void SetLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights);
  void SetRender(const v1::RenderSettings& render);  // the fields set change, as on the server
  void SetStream(const v1::StreamSettings& stream);  // likewise
  void SetClipping(const v1::Clipping& clipping);
  void SetLabels(const v1::Labels& labels);
  void SetMeasurements(const std::vector<v1::Measurement>& measurements);
  void SetTime(const v1::Time& time);  // a time series' phase, playing and rate; the server steps it while playing
  void SetFusion(const v1::Fusion& fusion);  // how the second volume shows (the one the session began with)
  // Any event as it is (a script's line): shown as an edit where it is one.
  void Send(v1::SessionEvent event);
  // Posts the camera set since the last flush; whether there was one.
  bool Flush();
  bool camera_waiting() const;  // a camera set and not yet flushed

 private:
  struct Edit {
    v1::SessionEvent event;
    std::uint64_t ticket = 0;  // 0: not posted yet (a camera waiting for Flush)
  };
  void Record(v1::SessionEvent event, bool post_now);
  bool Answered(int kind, const Edit& edit) const;
  void Show();  // shown_ = server_ with every edit laid over it

  EventSink& sink_;
  bool started_ = false;
  v1::SessionState server_, shown_;
  ViewCamera camera_;
  std::map<int, Edit> edits_;  // by SessionEvent::kind_case: the newest of each kind
};

}  // namespace cinevol::viewer

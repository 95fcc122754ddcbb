// Everything cinevol-viewer does over the network, off the UI thread. The UI
// posts events and requests and reads the newest decoded frame and the
// connection's state; it never waits on the server.
//
// Threads: a worker connects, creates the session and attaches (or, given a
// grant, watches another's session: docs/sharing.md), then sends posted
// events (camera and pointer events coalesced: the newest wins); a requester runs
// posted requests (loads, uploads, snapshots) in order beside it, and a
// second one the quick reading calls (picks, slices), so that they never
// wait behind a minutes-long snapshot or upload; the
// stream's reader (a watch's: a thread that takes its messages) hands frames
// to the FrameDecoder, which keeps only the newest (a slow decoder skips
// frames, never queues). Each event posted gets a ticket, by which the shown
// session learns when the server has answered it (shown_session.h).
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "client.h"
#include "session_script.h"
#include "sharing_calls.h"
#include "viewer/frame_decoder.h"
#include "viewer/second_volume.h"
#include "viewer/shown_session.h"

namespace cinevol::viewer {

struct ConnectionSettings {
  ClientOptions client;
  cli::ScriptSession session;  // the volume (id, load or upload), preset or scene, stream settings
  // A grant's secret: watch the session it names (WatchSession) instead of
  // creating one; events go as the grant holder's (SendEvents).
  std::string grant;
  // A second volume the session starts with, where its scene names none (--fuse).
  FuseStart fuse;
};

enum class LinkState { kConnecting, kStreaming, kReconnecting, kFailed, kClosed };

// Which requester runs a request: long calls in order, or quick ones (a
// pick, a slice: a unary call with a deadline) beside them.
enum class Lane { kLong = 0, kQuick = 1 };

struct LinkStatus {
  LinkState state = LinkState::kConnecting;
  std::string message;  // for people: what is happening or what went wrong
};

class Connection {
 public:
  explicit Connection(ConnectionSettings settings);
  ~Connection();  // closes the session and stops every thread
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  LinkStatus status() const;
  // Set once the session exists: its scene (resolved), volume and device.
  std::optional<v1::CreateSessionResponse> session() const;
  std::optional<v1::VolumeInfo> volume() const;
  // The second volume's description, while the session fuses one (its glow's values).
  std::optional<v1::VolumeInfo> fused_volume() const;

  // Queues an event; returns its ticket. Camera and pointer events replace
  // one of their kind still waiting last (its ticket is dropped).
  std::uint64_t Post(v1::SessionEvent event);
  // Where the event of `ticket` stands: waiting, sent (as which seq), or dropped.
  Delivery DeliveryOf(std::uint64_t ticket) const;
  // Runs `request` with the client once connected; its errors go to `done`
  // (empty on success). Both run on the requester thread.
  void Request(std::function<void(Client&)> request, std::function<void(const std::string& error)> done,
               Lane lane = Lane::kLong);

  // The newest decoded frame since the last call, if any.
  std::optional<ViewFrame> TakeFrame();
  // When event `seq` went out (for event-to-frame latency); nullopt if unknown.
  std::optional<std::chrono::steady_clock::time_point> SentAt(std::uint64_t seq) const;
  // The sequence number of the newest event sent (0: none yet).
  std::uint64_t last_sent() const { return last_sent_; }
  // The server's newest warning notice since the last call ("" if none).
  std::string TakeWarning();
  // The session's newest state since the last call: what the viewer shows
  // (shown_session.h), and who presents, watches and points (docs/sharing.md).
  std::optional<v1::SessionState> TakeState();
  // Whether the server refused a grant holder's pointer since the last call.
  bool TakePointerRefused();
  bool watching() const { return !settings_.grant.empty(); }
  // No event waits to be sent and no request to finish.
  bool idle() const;
  // Raised when the connection closes: a long request (a snapshot) stops on it.
  const std::atomic<bool>& stopping() const { return stopping_; }

 private:
  void Work();                                       // connects, sends events
  void Serve(Lane lane);                             // runs requests, so that a long upload holds no event back
  void Start();                                      // connect, resolve the volume, create the session, attach
  void Watch(Client& client);                        // the grant's session instead
  // --fuse: the second volume in the request's scene, where that names none.
  void Fuse(Client& client, v1::CreateSessionRequest& request) const;
  void OnMessage(const v1::ServerMessage& message);  // on the stream's reader or the watch's
  std::optional<grpc::Status> Ended() const;         // the stream's or watch's end, once it ended
  bool Ending(const grpc::Status& status);           // says why; whether to try again
  void Detach();
  bool SendPending();
  void SendAsGrant();
  // Records where the tickets went: as `seq` (0: dropped); mu_ held.
  void DeliveredLocked(const std::vector<std::uint64_t>& tickets, std::uint64_t seq);
  void SetStatus(LinkState state, std::string message);

  const ConnectionSettings settings_;
  std::shared_ptr<Client> client_;  // set by the worker (mu_), shared with the requester
  std::string resolved_volume_;     // the volume id the first start found
  // The server's last state of a session whose stream ended: the next start
  // creates the session again from it (on resolved_volume_), as the client
  // library's failover does, so the view stays as it was.
  std::optional<v1::SessionState> carried_;
  std::unique_ptr<SessionStream> stream_;
  std::unique_ptr<SessionWatch> watch_;  // with a grant, instead of stream_
  std::jthread watch_reader_;            // hands the watch's messages to OnMessage

  mutable std::mutex mu_;
  std::condition_variable wake_;
  LinkStatus status_;
  std::string warning_;
  std::optional<v1::SessionState> state_;  // newest, not yet taken
  bool pointer_refused_ = false;
  std::optional<v1::CreateSessionResponse> session_;
  std::optional<v1::VolumeInfo> volume_, fused_volume_;
  struct Queued {
    std::uint64_t ticket;
    v1::SessionEvent event;
  };
  std::deque<Queued> events_;
  std::uint64_t next_ticket_ = 1;
  std::vector<std::uint64_t> sending_;  // tickets taken from the queue, not yet sent
  // Tickets sent (and their seq) or dropped (0), the newest few thousand,
  // with the stream's reattachments then: a seq counts on its own stream only.
  struct Delivered {
    std::uint64_t seq;
    int epoch;
  };
  std::map<std::uint64_t, Delivered> delivered_;
  std::atomic<int> epoch_{0};  // streams started, resumed and moved so far
  int first_epoch_ = 0;        // the current stream's first (worker thread)
  struct Requests {
    std::deque<std::pair<std::function<void(Client&)>, std::function<void(const std::string&)>>> waiting;
    bool running = false;
  };
  std::array<Requests, 2> requests_;  // by Lane
  std::map<std::uint64_t, std::chrono::steady_clock::time_point> sent_at_;
  std::atomic<std::uint64_t> last_sent_{0};
  std::atomic<bool> stopping_{false};

  FrameDecoder decoder_;
  std::thread worker_, requester_, quick_requester_;
};

}  // namespace cinevol::viewer

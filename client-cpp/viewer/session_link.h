// The session link: the viewer's connection to its session (or, by a grant,
// to another's) and the session as it shows it. Each UI turn it adopts a new
// session, hands the server's newest state to the shown session, and says
// who drives; the rooms edit the shown session, which sends their edits
// through here while this viewer drives.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "placement.h"
#include "viewer/connection.h"
#include "viewer/shown_session.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

class SessionLink : private EventSink {
 public:
  SessionLink(ViewerContext& context, ConnectionSettings settings);
  ~SessionLink();

  // Connects, starting the session at `width` x `height` pixels.
  void Connect(int width, int height);
  // Opens volume `volume_id` instead, in `scene` (a presentation state's)
  // or the new volume's default preset: a new connection (the old one closes
  // on a thread of its own).
  void SwitchVolume(const std::string& volume_id, std::optional<v1::Scene> scene = std::nullopt);

  // What a UI turn brought.
  struct Turn {
    bool new_session = false;  // a session began (another volume, or one created again after a lost server)
    bool new_state = false;    // the server's state arrived
  };
  Turn Update();
  // Posts the camera the mouse set this turn: one camera event per displayed frame.
  void FlushCamera();
  // The window's frame area is `width` x `height` pixels: the session's
  // viewport follows once it has held still for a moment.
  void FollowViewport(int width, int height);
  bool ViewportPending(int width, int height) const;  // the frame area is not yet the session's size

  ShownSession& shown() { return shown_; }
  const ShownSession& shown() const { return shown_; }
  const std::string& session_id() const { return session_id_; }
  const std::optional<v1::VolumeInfo>& volume() const { return volume_; }  // none while watching
  // The second volume's description while the session fuses one (none while watching).
  const std::optional<v1::VolumeInfo>& fused_volume() const { return fused_volume_; }
  // Where the volume lies: the session's state says, else the volume's description.
  std::optional<Placement> placement() const;
  const ViewCamera& home() const { return home_; }  // where the session started (Home, Space)
  // The transfer-function presets the server offers (ServerStatus.presets; empty until it says).
  const std::vector<std::string>& presets() const { return presets_; }
  int viewport_width() const { return viewport_w_; }
  int viewport_height() const { return viewport_h_; }

  // Who drives (docs/sharing.md).
  bool Watching() const { return watching_; }  // another's session, by a grant
  const std::string& grant() const { return settings_.grant; }  // its secret: never shown or printed
  bool Presents() const;  // this viewer is the presenter (the owner also while nobody else is)
  bool Drives() const override;  // its events go to the session now
  const std::string& me() const { return me_; }  // this viewer's name as the server writes it ("": not known yet)
  void LearnName(std::string name) { me_ = std::move(name); }
  // The newest state while the stream lives (a lost one's says nothing of the session now).
  const v1::SessionState* live_state() const { return live_ ? &shown_.server() : nullptr; }

  Connection& connection() { return *connection_; }
  const Connection& connection() const { return *connection_; }
  LinkStatus status() const { return connection_->status(); }
  // A pointer event: a viewer's too, as it is no drive.
  void PostPointer(const v1::Pointer& pointer);

 private:
  std::uint64_t Post(v1::SessionEvent event) override { return connection_->Post(std::move(event)); }
  Delivery DeliveryOf(std::uint64_t ticket) const override { return connection_->DeliveryOf(ticket); }
  bool AdoptSession();

  ViewerContext& context_;
  ConnectionSettings settings_;
  const bool watching_;
  std::unique_ptr<Connection> connection_;
  std::vector<std::jthread> retired_;  // closing the connections of earlier volumes
  std::string session_id_;             // of the session shown
  std::optional<v1::VolumeInfo> volume_, fused_volume_;
  ShownSession shown_{*this};
  ViewCamera home_;
  std::string me_;
  bool live_ = false;
  std::vector<std::string> presets_;
  // Viewport resizes wait until the window stops changing.
  int viewport_w_ = 0, viewport_h_ = 0, pending_w_ = 0, pending_h_ = 0;
  Clock::time_point pending_since_;
};

}  // namespace cinevol::viewer

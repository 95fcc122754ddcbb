// The session link: see session_link.h.
#include "viewer/session_link.h"

#include "viewer/sharing_view.h"

namespace cinevol::viewer {
namespace {

constexpr auto kResizeSettle = std::chrono::milliseconds(250);

}  // namespace

SessionLink::SessionLink(ViewerContext& context, ConnectionSettings settings)
    : context_(context), settings_(std::move(settings)), watching_(!settings_.grant.empty()) {}

SessionLink::~SessionLink() {
  connection_.reset();  // closes the session
  retired_.clear();     // joins the threads closing earlier sessions
}

void SessionLink::Connect(int width, int height) {
  viewport_w_ = width;
  viewport_h_ = height;
  settings_.session.viewport.set_width(width);
  settings_.session.viewport.set_height(height);
  connection_ = std::make_unique<Connection>(settings_);
  // A grant's holder is named after its grant until its pointer's echo says otherwise.
  me_ = watching_ ? GuessedHolderName(settings_.grant) : "";
  connection_->Request(
      [this](Client& client) {
        const v1::ServerStatus status = client.Status();
        std::vector<std::string> presets(status.presets().begin(), status.presets().end());
        context_.ui.Later([this, presets = std::move(presets)] { presets_ = presets; });
      },
      [](const std::string&) {});  // a server that will not say (a link's holder has no token): no list
}

void SessionLink::SwitchVolume(const std::string& volume_id, std::optional<v1::Scene> scene) {
  cli::ScriptSession& s = settings_.session;
  s.volume = volume_id;
  s.load.clear();
  s.upload.clear();
  s.series.reset();
  s.preset.clear();  // without a scene: the new volume's default
  s.scene = std::move(scene);
  settings_.fuse = {};  // --fuse was for the volume the viewer started on
  // Closing the old session may wait on the network: not on this thread.
  retired_.emplace_back([old = std::move(connection_)]() mutable { old.reset(); });
  session_id_.clear();
  volume_.reset();
  fused_volume_.reset();
  live_ = false;
  shown_.Clear();
  Connect(viewport_w_, viewport_h_);
}

bool SessionLink::AdoptSession() {
  const std::optional<v1::CreateSessionResponse> created = connection_->session();
  if (!created || created->session_id() == session_id_) return false;
  // The server lost our session and the connection created it again from
  // the server's last state of it: Home stays where this volume began.
  const bool again = !session_id_.empty() && volume_ && connection_->volume() &&
                     volume_->id() == connection_->volume()->id();
  session_id_ = created->session_id();
  volume_ = connection_->volume();
  fused_volume_ = connection_->fused_volume();
  v1::SessionState first;  // until the state the attach brings
  *first.mutable_scene() = created->scene();
  *first.mutable_stream() = settings_.session.stream;
  first.mutable_viewport()->set_width(viewport_w_);
  first.mutable_viewport()->set_height(viewport_h_);
  shown_.Start(std::move(first));
  if (!again) home_ = shown_.camera();
  me_.clear();  // the sharing room asks the server who owns it
  return true;
}

SessionLink::Turn SessionLink::Update() {
  Turn turn;
  if (std::string warning = connection_->TakeWarning(); !warning.empty()) context_.notice = warning;
  turn.new_session = AdoptSession();
  live_ = live_ && connection_->status().state == LinkState::kStreaming;
  if (std::optional<v1::SessionState> state = connection_->TakeState()) {
    turn.new_state = true;
    live_ = true;
    if (!shown_.started()) {  // a grant's holder: the session as it joins it
      shown_.Start(std::move(*state));
      home_ = shown_.camera();
    } else {
      shown_.Adopt(std::move(*state));
    }
  }
  shown_.Settle();
  return turn;
}

void SessionLink::FlushCamera() {
  if (Drives()) shown_.Flush();
}

void SessionLink::FollowViewport(int width, int height) {
  if (watching_) return;  // the owner's window sets the session's size; its frames are fitted here
  if (width == viewport_w_ && height == viewport_h_) return;
  if (width != pending_w_ || height != pending_h_) {
    pending_w_ = width;
    pending_h_ = height;
    pending_since_ = Clock::now();
    return;
  }
  if (Clock::now() - pending_since_ < kResizeSettle || session_id_.empty()) return;
  viewport_w_ = width;
  viewport_h_ = height;
  if (!Drives()) return;
  v1::SessionEvent e;
  e.mutable_resize()->set_width(width);
  e.mutable_resize()->set_height(height);
  connection_->Post(std::move(e));
}

bool SessionLink::ViewportPending(int width, int height) const {
  return !watching_ && (width != viewport_w_ || height != viewport_h_);
}

std::optional<Placement> SessionLink::placement() const {
  if (shown_.started() && shown_.state().has_placement()) return Placement::Of(shown_.state().placement());
  if (volume_) return Placement::Of(*volume_);
  return std::nullopt;
}

bool SessionLink::Presents() const {
  const std::string presenter = live_ ? shown_.server().presenter() : "";
  if (!watching_ && (presenter.empty() || me_.empty())) return true;  // one's own, until told otherwise
  return !presenter.empty() && presenter == me_;
}

bool SessionLink::Drives() const { return watching_ ? Presents() : !session_id_.empty(); }

void SessionLink::PostPointer(const v1::Pointer& pointer) {
  v1::SessionEvent e;
  *e.mutable_pointer() = pointer;
  connection_->Post(std::move(e));
}

}  // namespace cinevol::viewer

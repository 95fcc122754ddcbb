// Sharing's calls, the state heard and the pointer sent.
#include "viewer/sharing.h"

#include <fmt/format.h>

namespace cinevol::viewer {
namespace {

google::protobuf::Value GrantValue(const v1::Grant& grant) {
  google::protobuf::Value v;
  auto& fields = *v.mutable_struct_value()->mutable_fields();
  fields["id"] = TextValue(grant.id());
  fields["holder"] = TextValue(HolderName(grant));
  fields["role"] = TextValue(RoleName(grant.role()));
  fields["watching"] = NumberValue(grant.watching());
  return v;
}

}  // namespace

const char* RoleName(v1::ShareRole role) { return role == v1::PRESENTER ? "presenter" : "viewer"; }

Sharing::Sharing(ViewerContext& context, SessionLink& link, std::string server_address, bool own_server)
    : context_(context), link_(link), server_address_(std::move(server_address)), own_server_(own_server) {}

void Sharing::Forget() {
  ++generation_;
  busy_ = 0;
}

void Sharing::StartOver() {
  made.reset();
  grants.clear();
  status.clear();
  failed = false;
  Forget();
  seen_ = false;
  reported_.clear();
  pointer_ = PointerShare();
  pointer_refused_ = false;
  // The session's owner as ServerStatus names it: what presenter and pointers say.
  link_.connection().Request(
      [this, id = link_.session_id(), generation = generation_](Client& client) {
        const v1::ServerStatus server = client.Status();
        for (const v1::SessionStatus& s : server.sessions()) {
          if (s.session_id() != id) continue;
          context_.ui.Later([this, generation, owner = s.owner()] {
            if (generation == generation_) link_.LearnName(owner);
          });
        }
      },
      [](const std::string&) {}, Lane::kQuick);
}

void Sharing::Follow(const SessionLink::Turn& turn, bool panel_open) {
  const v1::SessionState* state = link_.live_state();
  if (!state) {  // a lost or ended stream says nothing of the session now
    seen_ = false;
    return;
  }
  if (!turn.new_state) return;
  const bool first = !seen_;
  seen_ = true;
  if (const auto sent = pointer_.sent()) {  // one's own pointer, as the server names it
    if (auto name = EchoedName(*state, sent->x, sent->y)) link_.LearnName(*name);
  }
  const bool handed_over = !first && presenter_ != state->presenter();
  if (handed_over) pointer_refused_ = false;  // a hand-over may allow it now
  const bool changed = first || handed_over || viewers_ != state->viewers();
  presenter_ = state->presenter();
  viewers_ = state->viewers();
  if (changed && panel_open) ListShares();  // the grants' watchers and roles
  Report(*state);
}

void Sharing::Report(const v1::SessionState& s) {
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  const std::string banner = PresenceLine(s, link_.Presents(), link_.Watching());
  fields["presenter"] = TextValue(s.presenter());
  fields["viewers"] = NumberValue(s.viewers());
  fields["banner"] = TextValue(banner);
  fields["drives"].set_bool_value(link_.Drives());
  std::string said = fmt::format("{}|{}|{}|{}", s.presenter(), s.viewers(), banner, link_.Drives());
  auto& pointers = *fields["pointers"].mutable_list_value();
  for (const v1::SharedPointer& p : s.pointers()) {
    if (p.who() == link_.me()) continue;
    *pointers.add_values() = TextValue(p.who());
    said += "|" + p.who();
  }
  // Changes only: pointers move many times a second.
  if (said == reported_) return;
  reported_ = said;
  context_.log.Report("sharing", report);
}

void Sharing::SharePointer() {
  if (link_.connection().TakePointerRefused()) {
    pointer_refused_ = true;
    context_.notice = "your pointer is not shown to the others: this grant does not share it";
  }
  // While anyone watches (a grant's holder counts itself).
  const v1::SessionState* state = link_.live_state();
  if (!state || state->viewers() == 0 || pointer_refused_) return;
  if (std::optional<v1::Pointer> pointer = pointer_.Due(Clock::now())) link_.PostPointer(*pointer);
}

void Sharing::Call(const std::string& action, std::function<std::function<void()>(Client&)> call) {
  ++busy_;
  failed = false;
  link_.connection().Request(
      [this, action, call = std::move(call), generation = generation_](Client& client) {
        std::function<void()> then;
        try {
          then = call(client);
        } catch (const RpcError& e) {
          then = [this, action, code = e.code(), text = std::string(e.what())] { Failed(action, code, text); };
        } catch (const std::exception& e) {
          then = [this, action, text = std::string(e.what())] { Failed(action, grpc::StatusCode::UNKNOWN, text); };
        }
        context_.ui.Later([this, generation, then = std::move(then)] {
          if (generation != generation_) return;  // another session since
          --busy_;
          then();
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void Sharing::Failed(const std::string& action, grpc::StatusCode code, const std::string& message) {
  status = message;
  failed = true;
  google::protobuf::Struct report;
  (*report.mutable_fields())["error"] = TextValue(StatusCodeName(code));
  (*report.mutable_fields())["message"] = TextValue(message);
  context_.log.Report(action, report);
}

void Sharing::Share(v1::ShareSessionRequest request) {
  if (link_.session_id().empty() || link_.Watching()) return;
  request.set_session_id(link_.session_id());
  status = "sharing...";
  Call("share", [this, request](Client& client) -> std::function<void()> {
    return [this, grant = client.Share(request)] { Shared(grant); };
  });
}

void Sharing::Shared(const v1::Grant& grant) {
  made = grant;
  status = fmt::format("shared with {} as {}", HolderName(grant), RoleName(grant.role()));
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields = GrantValue(grant).struct_value().fields();
  fields["secret"] = TextValue(grant.secret());  // a script asked for it, as the panel shows it
  context_.log.Report("share", report);
  ListShares();
}

void Sharing::ListShares() {
  if (link_.session_id().empty() || link_.Watching()) return;
  Call("listShares", [this, id = link_.session_id()](Client& client) -> std::function<void()> {
    return [this, listed = client.ListShares(id)] {
      grants = listed;
      google::protobuf::Struct report;
      auto& list = *(*report.mutable_fields())["grants"].mutable_list_value();
      for (const v1::Grant& g : listed) *list.add_values() = GrantValue(g);
      context_.log.Report("listShares", report);
    };
  });
}

void Sharing::Revoke(const std::string& grant_id) {
  if (link_.session_id().empty() || link_.Watching()) return;
  Call("revoke", [this, id = link_.session_id(), grant_id](Client& client) -> std::function<void()> {
    return [this, grant_id, ended = client.RevokeShare(id, grant_id)] {
      status = fmt::format("revoked {}: {} stream{} ended", grant_id, ended, ended == 1 ? "" : "s");
      if (made && made->id() == grant_id) made.reset();
      google::protobuf::Struct report;
      (*report.mutable_fields())["grant"] = TextValue(grant_id);
      (*report.mutable_fields())["streamsEnded"] = NumberValue(ended);
      context_.log.Report("revoke", report);
      ListShares();
    };
  });
}

void Sharing::HandOver(const std::string& grant_id) {
  v1::HandOverRequest request;
  request.set_session_id(link_.session_id());  // a grant's holder leaves it empty: its grant names the session
  request.set_grant_id(grant_id);
  if (link_.Watching()) request.set_grant(link_.grant());  // the presenter gives the role back
  Call("handover", [this, request](Client& client) -> std::function<void()> {
    return [this, presenter = client.HandOver(request)] {
      status = presenter + " presents";
      google::protobuf::Struct report;
      (*report.mutable_fields())["presenter"] = TextValue(presenter);
      context_.log.Report("handover", report);
      ListShares();
    };
  });
}

}  // namespace cinevol::viewer

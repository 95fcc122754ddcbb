// Sharing a session (docs/viewer.md, "Sharing"; docs/sharing.md): the owner's
// Share panel (grants, hand-over, take back), a grant holder's panel, the line
// over the view, everyone else's pointers and this viewer's own. The words and
// the pointer's pace are in sharing_view.h. The calls go on the connection's
// quick lane: never behind a still.
#include <SDL.h>
#include <fmt/format.h>
#include <google/protobuf/struct.pb.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>
#include <ctime>
#include <functional>

#include "viewer/viewer_app.h"

namespace cinevol::viewer {
namespace {

struct Expiry {
  const char* name;
  std::uint32_t seconds;
};
constexpr Expiry kExpiries[] = {{"15 minutes", 900}, {"1 hour", 3600}, {"2 hours", 7200},
                                {"8 hours", 28800},  {"1 day", 86400}, {"1 week", 604800}};

const char* RoleName(v1::ShareRole role) { return role == v1::PRESENTER ? "presenter" : "viewer"; }

google::protobuf::Value GrantValue(const v1::Grant& grant) {
  google::protobuf::Value v;
  auto& fields = *v.mutable_struct_value()->mutable_fields();
  fields["id"] = TextValue(grant.id());
  fields["holder"] = TextValue(HolderName(grant));
  fields["role"] = TextValue(RoleName(grant.role()));
  fields["watching"] = NumberValue(grant.watching());
  return v;
}

// What a grant's holder types to join: the server as this viewer reached it.
std::string JoinCommand(const App& app, const v1::Grant& grant) {
  return fmt::format("cinevol-viewer --server {} --grant {}{}", app.options.connection.server, grant.secret(),
                     grant.principal().empty() ? "" : fmt::format(" --token <{}'s token>", grant.principal()));
}

// A colour of its own for each name.
ImU32 PointerColour(const std::string& who) {
  const float hue = float(std::hash<std::string>{}(who) % 360) / 360.0f;
  return ImColor::HSV(hue, 0.6f, 1.0f);
}

}  // namespace

// --------------------------------------------------------- who drives

bool App::Presents() const {
  const std::string presenter = sharing.state ? sharing.state->presenter() : "";
  if (!Watching() && (presenter.empty() || sharing.me.empty())) return true;  // one's own, until told otherwise
  return !presenter.empty() && presenter == sharing.me;
}

bool App::Drives() const { return Watching() ? Presents() : !session_id.empty(); }

void App::LearnOwnName() {
  // The session's owner as ServerStatus names it: what presenter and pointers say.
  connection->Request(
      [this, id = session_id, generation = sharing.generation](Client& client) {
        const v1::ServerStatus status = client.Status();
        for (const v1::SessionStatus& s : status.sessions()) {
          if (s.session_id() != id) continue;
          Later([this, generation, owner = s.owner()] {
            if (generation == sharing.generation) sharing.me = owner;
          });
        }
      },
      [](const std::string&) {}, Lane::kQuick);
}

void App::FollowSharing() {
  // A lost or ended stream's last state says nothing of the session now.
  if (connection->status().state != LinkState::kStreaming) sharing.state.reset();
  std::optional<v1::SessionState> state = connection->TakeState();
  if (!state) return;
  const bool first = !sharing.state;
  const std::string presenter = first ? "" : sharing.state->presenter();
  const std::uint32_t viewers = first ? 0 : sharing.state->viewers();
  if (const auto sent = sharing.pointer.sent()) {  // one's own pointer, as the server names it
    if (auto name = EchoedName(*state, sent->x, sent->y)) sharing.me = *name;
  }
  if (!first && presenter != state->presenter()) sharing.pointer_refused = false;  // a hand-over may allow it now
  sharing.state = std::move(state);
  // Another drives: the view and panels follow the session (a grant's
  // holder starts from it, and goes on from it once it presents).
  if (!Presents() || (first && Watching())) {
    ShowScene(sharing.state->scene());
    if (Watching()) {  // a watcher shows the session's measurements, and has none of its own
      const auto& shared = sharing.state->scene().measurements();
      reading.measurements.assign(shared.begin(), shared.end());
    }
    stream = sharing.state->stream();
    if (first && Watching()) home = camera;  // Home goes back to where it joined
  }
  const bool changed = first || presenter != sharing.state->presenter() || viewers != sharing.state->viewers();
  if (changed && panels.share) ListShares();  // the grants' watchers and roles
  ReportSharing();
}

void App::ReportSharing() {
  const v1::SessionState& s = *sharing.state;
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  const std::string banner = PresenceLine(s, Presents(), Watching());
  fields["presenter"] = TextValue(s.presenter());
  fields["viewers"] = NumberValue(s.viewers());
  fields["banner"] = TextValue(banner);
  fields["drives"].set_bool_value(Drives());
  std::string said = fmt::format("{}|{}|{}|{}", s.presenter(), s.viewers(), banner, Drives());
  auto& pointers = *fields["pointers"].mutable_list_value();
  for (const v1::SharedPointer& p : s.pointers()) {
    if (p.who() == sharing.me) continue;
    *pointers.add_values() = TextValue(p.who());
    said += "|" + p.who();
  }
  // Changes only: pointers move many times a second.
  if (said == sharing.reported) return;
  sharing.reported = said;
  Report("sharing", report);
}

// ------------------------------------------------------------ pointer

void App::PointAt(std::optional<PointerShare::At> at) { sharing.pointer.MoveTo(at); }

void App::SharePointer() {
  if (connection->TakePointerRefused()) {
    sharing.pointer_refused = true;
    notice = "your pointer is not shown to the others: this grant does not share it";
  }
  // While anyone watches (a grant's holder counts itself).
  if (!sharing.state || sharing.state->viewers() == 0 || sharing.pointer_refused) return;
  if (std::optional<v1::Pointer> pointer = sharing.pointer.Due(Clock::now())) {
    v1::SessionEvent e;
    *e.mutable_pointer() = *pointer;
    connection->Post(std::move(e));  // a viewer's too: not a drive
  }
}

// ------------------------------------------------------------- calls

void App::SharingCall(const std::string& action, std::function<std::function<void()>(Client&)> call) {
  ++sharing.busy;
  sharing.failed = false;
  connection->Request(
      [this, action, call = std::move(call), generation = sharing.generation](Client& client) {
        std::function<void()> then;
        try {
          then = call(client);
        } catch (const RpcError& e) {
          then = [this, action, code = e.code(), text = std::string(e.what())] { SharingFailed(action, code, text); };
        } catch (const std::exception& e) {
          then = [this, action, text = std::string(e.what())] {
            SharingFailed(action, grpc::StatusCode::UNKNOWN, text);
          };
        }
        Later([this, generation, then = std::move(then)] {
          if (generation != sharing.generation) return;  // another session since
          --sharing.busy;
          then();
        });
      },
      [](const std::string&) {}, Lane::kQuick);
}

void App::SharingFailed(const std::string& action, grpc::StatusCode code, const std::string& message) {
  sharing.status = message;
  sharing.failed = true;
  google::protobuf::Struct report;
  (*report.mutable_fields())["error"] = TextValue(StatusCodeName(code));
  (*report.mutable_fields())["message"] = TextValue(message);
  Report(action, report);
}

void App::Share(v1::ShareSessionRequest request) {
  if (session_id.empty() || Watching()) return;
  request.set_session_id(session_id);
  sharing.status = "sharing...";
  SharingCall("share", [this, request](Client& client) -> std::function<void()> {
    return [this, grant = client.Share(request)] { Shared(grant); };
  });
}

void App::Shared(const v1::Grant& grant) {
  sharing.made = grant;
  sharing.status = fmt::format("shared with {} as {}", HolderName(grant), RoleName(grant.role()));
  google::protobuf::Struct report;
  auto& fields = *report.mutable_fields();
  fields = GrantValue(grant).struct_value().fields();
  fields["secret"] = TextValue(grant.secret());  // a script asked for it, as the panel shows it
  Report("share", report);
  ListShares();
}

void App::ListShares() {
  if (session_id.empty() || Watching()) return;
  SharingCall("listShares", [this, id = session_id](Client& client) -> std::function<void()> {
    return [this, grants = client.ListShares(id)] {
      sharing.grants = grants;
      google::protobuf::Struct report;
      auto& list = *(*report.mutable_fields())["grants"].mutable_list_value();
      for (const v1::Grant& g : grants) *list.add_values() = GrantValue(g);
      Report("listShares", report);
    };
  });
}

void App::Revoke(const std::string& grant_id) {
  if (session_id.empty() || Watching()) return;
  SharingCall("revoke", [this, id = session_id, grant_id](Client& client) -> std::function<void()> {
    return [this, grant_id, ended = client.RevokeShare(id, grant_id)] {
      sharing.status = fmt::format("revoked {}: {} stream{} ended", grant_id, ended, ended == 1 ? "" : "s");
      if (sharing.made && sharing.made->id() == grant_id) sharing.made.reset();
      google::protobuf::Struct report;
      (*report.mutable_fields())["grant"] = TextValue(grant_id);
      (*report.mutable_fields())["streamsEnded"] = NumberValue(ended);
      Report("revoke", report);
      ListShares();
    };
  });
}

void App::HandOver(const std::string& grant_id) {
  v1::HandOverRequest request;
  request.set_session_id(session_id);  // a grant's holder leaves it empty: its grant names the session
  request.set_grant_id(grant_id);
  if (Watching()) request.set_grant(options.grant);  // the presenter gives the role back
  SharingCall("handover", [this, request](Client& client) -> std::function<void()> {
    return [this, presenter = client.HandOver(request)] {
      sharing.status = presenter + " presents";
      google::protobuf::Struct report;
      (*report.mutable_fields())["presenter"] = TextValue(presenter);
      Report("handover", report);
      ListShares();
    };
  });
}

// ------------------------------------------------------------- panels

namespace {

v1::ShareSessionRequest RequestOf(const ShareForm& form) {
  v1::ShareSessionRequest request;
  if (!form.link) request.set_principal(form.principal);
  request.set_role(form.presenter ? v1::PRESENTER : v1::VIEWER);
  request.set_expires_seconds(kExpiries[form.expiry].seconds);
  request.set_allow_pointer(form.allow_pointer);
  return request;
}

void ShareFields(App& app) {
  ShareForm& form = app.sharing.form;
  if (ImGui::RadioButton("a link", form.link)) form.link = true;
  ImGui::SameLine();
  if (ImGui::RadioButton("a user", !form.link)) form.link = false;
  if (!form.link) ImGui::InputTextWithHint("principal", "a name in the server's token file", &form.principal);
  int role = form.presenter ? 1 : 0;
  static const char* kRoles[] = {"viewer: watches", "presenter: drives"};
  if (ImGui::Combo("role", &role, kRoles, IM_ARRAYSIZE(kRoles))) form.presenter = role == 1;
  if (ImGui::BeginCombo("expires in", kExpiries[form.expiry].name)) {
    for (int i = 0; i < IM_ARRAYSIZE(kExpiries); ++i) {
      if (ImGui::Selectable(kExpiries[i].name, i == form.expiry)) form.expiry = i;
    }
    ImGui::EndCombo();
  }
  bool pointer = form.allow_pointer || form.presenter;
  ImGui::BeginDisabled(form.presenter);  // a presenter's pointer is always shown
  if (ImGui::Checkbox("show their pointer to everyone", &pointer)) form.allow_pointer = pointer;
  ImGui::EndDisabled();
  ImGui::BeginDisabled(!form.link && form.principal.empty());
  if (ImGui::Button("Share")) app.Share(RequestOf(form));
  ImGui::EndDisabled();
}

// The newest grant's secret, with the command that joins by it: shown here
// once, as the server keeps no copy it could show again.
void MadeGrant(App& app) {
  if (!app.sharing.made) return;
  const v1::Grant grant = *app.sharing.made;
  ImGui::Separator();
  ImGui::TextWrapped("%s, %s, expires %s. Its secret shows only here:", HolderName(grant).c_str(),
                     RoleName(grant.role()), ExpiresIn(grant.expires_unix_seconds(), std::time(nullptr)).c_str());
  std::string secret = grant.secret();
  ImGui::InputText("##secret", &secret, ImGuiInputTextFlags_ReadOnly);
  const std::string command = JoinCommand(app, grant);
  if (ImGui::Button("Copy secret")) SDL_SetClipboardText(grant.secret().c_str());
  ImGui::SameLine();
  if (ImGui::Button("Copy command")) SDL_SetClipboardText(command.c_str());
  ImGui::SameLine();
  if (ImGui::Button("Hide")) app.sharing.made.reset();
  ImGui::TextWrapped("%s", command.c_str());
  if (app.local_server) Hint("this viewer's own server listens on loopback: only this machine can join it");
}

// Who presents, and the owner's way back.
void PresenterLine(App& app) {
  if (!app.sharing.state) return;
  if (app.Presents()) {
    ImGui::TextWrapped("You present · %u watching", app.sharing.state->viewers());
    return;
  }
  ImGui::TextWrapped("%s presents · %u watching", app.sharing.state->presenter().c_str(), app.sharing.state->viewers());
  if (ImGui::Button("Take back")) app.HandOver("");
}

// The session's grants, each with its revocation and hand-over.
void GrantsTable(App& app) {
  if (app.sharing.grants.empty()) {
    Hint("not shared");
    return;
  }
  constexpr ImGuiTableFlags kFlags =
      ImGuiTableFlags_Borders | ImGuiTableFlags_RowBg | ImGuiTableFlags_ScrollX | ImGuiTableFlags_SizingFixedFit;
  if (!ImGui::BeginTable("grants", 5, kFlags)) return;
  for (const char* column : {"", "for", "role", "expires", "watching"}) ImGui::TableSetupColumn(column);
  ImGui::TableHeadersRow();
  auto cell = [](const std::string& text) {
    ImGui::TableNextColumn();
    ImGui::TextUnformatted(text.c_str());
  };
  std::string revoke, hand_over;  // acted on after the table: they change the list drawn
  for (const v1::Grant& grant : app.sharing.grants) {
    ImGui::TableNextRow();
    ImGui::PushID(grant.id().c_str());
    ImGui::TableNextColumn();  // the buttons first: the panel is narrow
    if (ImGui::SmallButton("Revoke")) revoke = grant.id();
    if (grant.role() != v1::PRESENTER) {
      ImGui::SameLine();
      if (ImGui::SmallButton("Make presenter")) hand_over = grant.id();
    }
    ImGui::PopID();
    cell(HolderName(grant));
    cell(RoleName(grant.role()));
    cell(ExpiresIn(grant.expires_unix_seconds(), std::time(nullptr)));
    cell(std::to_string(grant.watching()));
  }
  ImGui::EndTable();
  if (!revoke.empty()) app.Revoke(revoke);
  if (!hand_over.empty()) app.HandOver(hand_over);
}

void StatusLine(const SharingState& sharing) {
  if (sharing.status.empty()) return;
  if (sharing.failed) ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.55f, 0.45f, 1.0f));
  ImGui::TextWrapped("%s", sharing.status.c_str());
  if (sharing.failed) ImGui::PopStyleColor();
}

void DrawPointers(App& app, ImDrawList& draw) {
  const Rect shown = app.ShownFrame();
  if (shown.w <= 0) return;
  for (const v1::SharedPointer& p : app.sharing.state->pointers()) {
    if (p.who() == app.sharing.me) continue;  // one's own is the mouse
    const ImVec2 at{shown.x + p.x() * shown.w, shown.y + p.y() * shown.h};
    const ImU32 colour = PointerColour(p.who());
    draw.AddCircleFilled(at, 5, colour);
    draw.AddCircle(at, 6, IM_COL32(0, 0, 0, 200), 0, 1.5f);
    draw.AddText({at.x + 9, at.y - 7}, colour, p.who().c_str());
  }
}

}  // namespace

void SharePanel(App& app) {
  if (app.session_id.empty()) {
    Hint("once the session has started");
    return;
  }
  ShareFields(app);
  MadeGrant(app);
  ImGui::Separator();
  PresenterLine(app);
  GrantsTable(app);
  if (ImGui::SmallButton("Refresh")) app.ListShares();
  StatusLine(app.sharing);
}

void WatchingPanel(App& app) {
  if (!app.sharing.state) {
    const bool over = app.connection->status().state == LinkState::kFailed;
    ImGui::TextWrapped(
        "%s", over ? "no longer watching: the message over the view says why" : "joining the shared session...");
    return;
  }
  ImGui::TextWrapped("%s", PresenceLine(*app.sharing.state, app.Presents(), true).c_str());
  if (app.Presents()) {
    Hint("you present: the camera, transfer function, lights and render settings are yours to change");
    if (ImGui::Button("Give the role back")) app.HandOver("");
  } else {
    Hint("the presenter drives: the view and the panels below follow the session");
  }
  StatusLine(app.sharing);
  ImGui::Separator();
}

void DrawSharingOverlay(App& app) {
  app.banner_area = {};
  if (!app.sharing.state) return;
  DrawPointers(app, *ImGui::GetBackgroundDrawList());
  const std::string line = PresenceLine(*app.sharing.state, app.Presents(), app.Watching());
  if (line.empty()) return;
  // Centred at the top of the view, wrapped where the view is narrow.
  const ImVec2 padding = ImGui::GetStyle().WindowPadding;
  const float width = std::min(ImGui::CalcTextSize(line.c_str()).x + 2 * padding.x + 1, app.frame_area.w - 20);
  const float height = ImGui::CalcTextSize(line.c_str(), nullptr, false, width - 2 * padding.x).y + 2 * padding.y;
  ImGui::SetNextWindowPos({app.frame_area.x + app.frame_area.w * 0.5f, app.frame_area.y + 10}, ImGuiCond_Always,
                          {0.5f, 0.0f});
  ImGui::SetNextWindowSize({width, height});
  ImGui::SetNextWindowBgAlpha(0.75f);
  ImGui::Begin("sharing", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoSavedSettings |
                   ImGuiWindowFlags_NoFocusOnAppearing);
  ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(0.55f, 0.85f, 1.0f, 1.0f));
  ImGui::TextWrapped("%s", line.c_str());
  ImGui::PopStyleColor();
  const ImVec2 pos = ImGui::GetWindowPos(), size = ImGui::GetWindowSize();
  app.banner_area = {pos.x, pos.y, size.x, size.y};
  ImGui::End();
}

}  // namespace cinevol::viewer

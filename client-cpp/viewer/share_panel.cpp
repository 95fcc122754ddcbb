// The Share panel (the owner's grants, hand-over, take back), a grant
// holder's panel, the line over a shared view and everyone else's pointers
// (docs/viewer.md, "Sharing"). The calls are the Sharing room's.
#include <SDL.h>
#include <fmt/format.h>
#include <imgui.h>
#include <imgui_stdlib.h>

#include <algorithm>
#include <ctime>
#include <functional>

#include "viewer/panels.h"

namespace cinevol::viewer {
namespace {

struct Expiry {
  const char* name;
  std::uint32_t seconds;
};
constexpr Expiry kExpiries[] = {{"15 minutes", 900}, {"1 hour", 3600}, {"2 hours", 7200},
                                {"8 hours", 28800},  {"1 day", 86400}, {"1 week", 604800}};

// What a grant's holder types to join: the server as this viewer reached it.
std::string JoinCommand(const Sharing& sharing, const v1::Grant& grant) {
  return fmt::format("cinevol-viewer --server {} --grant {}{}", sharing.server_address(), grant.secret(),
                     grant.principal().empty() ? "" : fmt::format(" --token <{}'s token>", grant.principal()));
}

// A colour of its own for each name.
ImU32 PointerColour(const std::string& who) {
  const float hue = float(std::hash<std::string>{}(who) % 360) / 360.0f;
  return ImColor::HSV(hue, 0.6f, 1.0f);
}

v1::ShareSessionRequest RequestOf(const ShareForm& form) {
  v1::ShareSessionRequest request;
  if (!form.link) request.set_principal(form.principal);
  request.set_role(form.presenter ? v1::PRESENTER : v1::VIEWER);
  request.set_expires_seconds(kExpiries[form.expiry].seconds);
  request.set_allow_pointer(form.allow_pointer);
  return request;
}

void ShareFields(Sharing& sharing) {
  ShareForm& form = sharing.form;
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
  if (ImGui::Button("Share")) sharing.Share(RequestOf(form));
  ImGui::EndDisabled();
}

// The newest grant's secret, with the command that joins by it: shown here
// once, as the server keeps no copy it could show again.
void MadeGrant(Sharing& sharing) {
  if (!sharing.made) return;
  const v1::Grant grant = *sharing.made;
  ImGui::Separator();
  ImGui::TextWrapped("%s, %s, expires %s. Its secret shows only here:", HolderName(grant).c_str(),
                     RoleName(grant.role()), ExpiresIn(grant.expires_unix_seconds(), std::time(nullptr)).c_str());
  std::string secret = grant.secret();
  ImGui::InputText("##secret", &secret, ImGuiInputTextFlags_ReadOnly);
  const std::string command = JoinCommand(sharing, grant);
  if (ImGui::Button("Copy secret")) SDL_SetClipboardText(grant.secret().c_str());
  ImGui::SameLine();
  if (ImGui::Button("Copy command")) SDL_SetClipboardText(command.c_str());
  ImGui::SameLine();
  if (ImGui::Button("Hide")) sharing.made.reset();
  ImGui::TextWrapped("%s", command.c_str());
  if (sharing.own_server()) Hint("this viewer's own server listens on loopback: only this machine can join it");
}

// Who presents, and the owner's way back.
void PresenterLine(Sharing& sharing, const SessionLink& link) {
  const v1::SessionState* state = link.live_state();
  if (!state) return;
  if (link.Presents()) {
    ImGui::TextWrapped("You present · %u watching", state->viewers());
    return;
  }
  ImGui::TextWrapped("%s presents · %u watching", state->presenter().c_str(), state->viewers());
  if (ImGui::Button("Take back")) sharing.HandOver("");
}

// The session's grants, each with its revocation and hand-over.
void GrantsTable(Sharing& sharing) {
  if (sharing.grants.empty()) {
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
  for (const v1::Grant& grant : sharing.grants) {
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
  if (!revoke.empty()) sharing.Revoke(revoke);
  if (!hand_over.empty()) sharing.HandOver(hand_over);
}

void StatusLine(const Sharing& sharing) {
  if (sharing.status.empty()) return;
  if (sharing.failed) ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.55f, 0.45f, 1.0f));
  ImGui::TextWrapped("%s", sharing.status.c_str());
  if (sharing.failed) ImGui::PopStyleColor();
}

void DrawPointers(const SessionLink& link, const Screen& screen, const v1::SessionState& state, ImDrawList& draw) {
  const Rect shown = screen.ShownFrame();
  if (shown.w <= 0) return;
  for (const v1::SharedPointer& p : state.pointers()) {
    if (p.who() == link.me()) continue;  // one's own is the mouse
    const ImVec2 at{shown.x + p.x() * shown.w, shown.y + p.y() * shown.h};
    const ImU32 colour = PointerColour(p.who());
    draw.AddCircleFilled(at, 5, colour);
    draw.AddCircle(at, 6, IM_COL32(0, 0, 0, 200), 0, 1.5f);
    draw.AddText({at.x + 9, at.y - 7}, colour, p.who().c_str());
  }
}

}  // namespace

void SharePanel(Sharing& sharing, const SessionLink& link) {
  if (link.session_id().empty()) {
    Hint("once the session has started");
    return;
  }
  ShareFields(sharing);
  MadeGrant(sharing);
  ImGui::Separator();
  PresenterLine(sharing, link);
  GrantsTable(sharing);
  if (ImGui::SmallButton("Refresh")) sharing.ListShares();
  StatusLine(sharing);
}

void WatchingPanel(Sharing& sharing, const SessionLink& link) {
  const v1::SessionState* state = link.live_state();
  if (!state) {
    const bool over = link.status().state == LinkState::kFailed;
    ImGui::TextWrapped(
        "%s", over ? "no longer watching: the message over the view says why" : "joining the shared session...");
    return;
  }
  ImGui::TextWrapped("%s", PresenceLine(*state, link.Presents(), true).c_str());
  if (link.Presents()) {
    Hint("you present: the camera, transfer function, lights and render settings are yours to change");
    if (ImGui::Button("Give the role back")) sharing.HandOver("");
  } else {
    Hint("the presenter drives: the view and the panels below follow the session");
  }
  StatusLine(sharing);
  ImGui::Separator();
}

void DrawSharingOverlay(const SessionLink& link, const Screen& screen, Rect& banner) {
  banner = {};
  const v1::SessionState* state = link.live_state();
  if (!state) return;
  DrawPointers(link, screen, *state, *ImGui::GetBackgroundDrawList());
  const std::string line = PresenceLine(*state, link.Presents(), link.Watching());
  const Rect frame = screen.frame_area();
  if (line.empty()) return;
  // Centred at the top of the view, wrapped where the view is narrow.
  const ImVec2 padding = ImGui::GetStyle().WindowPadding;
  const float width = std::min(ImGui::CalcTextSize(line.c_str()).x + 2 * padding.x + 1, frame.w - 20);
  const float height = ImGui::CalcTextSize(line.c_str(), nullptr, false, width - 2 * padding.x).y + 2 * padding.y;
  ImGui::SetNextWindowPos({frame.x + frame.w * 0.5f, frame.y + 10}, ImGuiCond_Always,
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
  banner = {pos.x, pos.y, size.x, size.y};
  ImGui::End();
}

}  // namespace cinevol::viewer

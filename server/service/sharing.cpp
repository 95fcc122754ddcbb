// Grants: made by the owner, checked on every call of their holders.
#include "service/sharing.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/log_safe.h"
#include "runtime/errors.h"

namespace cinevol::service {
namespace {

constexpr std::chrono::seconds kDefaultLifetime = std::chrono::hours(2);
constexpr std::uint32_t kMinLifetimeSeconds = 1, kMaxLifetimeSeconds = 7 * 24 * 3600;
constexpr std::size_t kMaxPrincipalLength = 256;

std::chrono::seconds LifetimeOf(std::uint32_t seconds) {
  if (seconds == 0) return kDefaultLifetime;
  if (seconds < kMinLifetimeSeconds || seconds > kMaxLifetimeSeconds) {
    throw InputError(fmt::format("expires_seconds: {} is outside [{}, {}] (a second to a week; 0: two hours)", seconds,
                                 kMinLifetimeSeconds, kMaxLifetimeSeconds));
  }
  return std::chrono::seconds(seconds);
}

GrantRole RoleOf(v1::ShareRole role) {
  switch (role) {
    case v1::SHARE_ROLE_UNSPECIFIED:
    case v1::VIEWER:
      return GrantRole::kViewer;
    case v1::PRESENTER:
      return GrantRole::kPresenter;
    default:
      throw InputError(fmt::format("role: unknown value {}", int(role)));
  }
}

}  // namespace

Sharing::Sharing(const Authenticator& authenticator, int max_grants_per_principal, FindAny find, FindOwned owned)
    : authenticator_(authenticator),
      grants_(max_grants_per_principal),
      find_(std::move(find)),
      owned_(std::move(owned)) {}

v1::Grant Sharing::ToProto(const Grant& grant, const Session* session) const {
  v1::Grant out;
  out.set_id(grant.id);
  out.set_session_id(grant.session_id);
  out.set_principal(grant.principal);
  out.set_role(grant.role == GrantRole::kPresenter ? v1::PRESENTER : v1::VIEWER);
  out.set_expires_unix_seconds(
      std::chrono::duration_cast<std::chrono::seconds>(grant.expires_wall.time_since_epoch()).count());
  out.set_allow_pointer(grant.allow_pointer);
  if (session) out.set_watching(std::uint32_t(session->Watching(grant.id)));
  return out;
}

v1::Grant Sharing::Share(const v1::ShareSessionRequest& request, const Principal& caller) {
  const std::shared_ptr<Session> session = owned_(request.session_id(), caller);
  if (request.principal().size() > kMaxPrincipalLength) {
    throw InputError(fmt::format("principal: {} bytes; at most {}", request.principal().size(), kMaxPrincipalLength));
  }
  Grant grant;
  grant.session_id = session->id();
  grant.created_by = caller.name;
  grant.principal = ValidUtf8(LogSafe(request.principal(), kMaxPrincipalLength));
  grant.role = RoleOf(request.role());
  grant.allow_pointer = request.allow_pointer() || grant.role == GrantRole::kPresenter;
  auto [made, secret] = grants_.Create(grant, LifetimeOf(request.expires_seconds()), request.restore_secret());
  if (made.role == GrantRole::kPresenter) MakePresenter(*session, made.id, made.holder());  // it takes over
  // The id names the grant in the log; the principal is a name the owner typed, the secret never appears.
  spdlog::info("session {}: shared as {} ({}, {})", session->id(), made.id, made.link() ? "link" : "principal",
               ToString(made.role));
  v1::Grant out = ToProto(made, session.get());
  out.set_secret(secret);
  return out;
}

v1::ListSharesResponse Sharing::List(const v1::ListSharesRequest& request, const Principal& caller) const {
  const std::shared_ptr<Session> session = owned_(request.session_id(), caller);
  v1::ListSharesResponse out;
  for (const Grant& grant : grants_.OfSession(session->id())) *out.add_grants() = ToProto(grant, session.get());
  return out;
}

v1::RevokeShareResponse Sharing::Revoke(const v1::RevokeShareRequest& request, const Principal& caller) {
  const std::shared_ptr<Session> session = owned_(request.session_id(), caller);
  const std::optional<Grant> grant = grants_.Find(request.grant_id());
  if (!grant || grant->session_id != session->id() || !grants_.Revoke(grant->id)) {
    throw RpcError::NotFound(
        fmt::format("grant_id: session '{}' has no grant '{}'", session->id(), LogSafe(request.grant_id())));
  }
  if (grant->role == GrantRole::kPresenter) session->SetPresenter(session->owner());
  v1::RevokeShareResponse out;
  out.set_streams_ended(std::uint32_t(session->EndWatchers(
      grant->id,
      RpcError::PermissionDenied(fmt::format("grant {} was revoked by the session's owner", grant->id)).status())));
  spdlog::info("session {}: grant {} revoked, {} streams ended", session->id(), grant->id, out.streams_ended());
  return out;
}

std::shared_ptr<Session> Sharing::OwnedOrPresented(const std::string& id, const Principal& caller) const {
  if (const std::shared_ptr<Session> session = find_(id)) {
    for (const Grant& grant : grants_.OfSession(session->id())) {
      if (grant.role == GrantRole::kPresenter && !grant.link() && grant.principal == caller.name) return session;
    }
  }
  return owned_(id, caller);
}

void Sharing::MakePresenter(Session& session, const std::string& grant_id, const std::string& presenter) {
  for (const Grant& grant : grants_.OfSession(session.id())) {
    grants_.SetRole(grant.id, grant.id == grant_id ? GrantRole::kPresenter : GrantRole::kViewer);
  }
  session.SetPresenter(presenter);
}

v1::HandOverResponse Sharing::HandOver(const v1::HandOverRequest& request, const grpc::CallbackServerContext& context) {
  std::shared_ptr<Session> session;
  if (request.grant().empty()) {
    session = owned_(request.session_id(), authenticator_.Authenticate(context));
  } else {
    GrantAccess access = Access(context, request.session_id(), request.grant());
    if (access.grant.role != GrantRole::kPresenter) {
      throw RpcError::PermissionDenied(
          fmt::format("grant {} is a viewer's: only the owner or the presenter hands the role over", access.grant.id));
    }
    session = std::move(access.session);
  }
  std::string presenter = session->owner();
  if (!request.grant_id().empty()) {
    const std::optional<Grant> next = grants_.Find(request.grant_id());
    if (!next || next->session_id != session->id()) {
      throw RpcError::NotFound(
          fmt::format("grant_id: session '{}' has no grant '{}'", session->id(), LogSafe(request.grant_id())));
    }
    presenter = next->holder();
  }
  MakePresenter(*session, request.grant_id(), presenter);
  v1::HandOverResponse out;
  out.set_presenter(presenter);
  return out;
}

GrantAccess Sharing::Access(const grpc::CallbackServerContext& context, const std::string& session_id,
                            const std::string& secret) const {
  const std::optional<Grant> grant = grants_.FindBySecret(secret);
  if (!grant) throw RpcError::PermissionDenied("grant: not valid (mistyped, revoked or expired)");
  if (!session_id.empty() && session_id != grant->session_id) {
    throw RpcError::PermissionDenied(fmt::format("grant {}: not for session '{}'", grant->id, LogSafe(session_id)));
  }
  if (!grant->link()) {  // a principal's grant: that principal's own token too
    const Principal caller = authenticator_.Authenticate(context);
    if (caller.name != grant->principal) {
      throw RpcError::PermissionDenied(
          fmt::format("grant {} is for another principal than {}", grant->id, LogSafe(caller.name)));
    }
  }
  std::shared_ptr<Session> session = find_(grant->session_id);
  if (!session) throw RpcError::NotFound(fmt::format("grant {}: its session has ended", grant->id));
  return {std::move(session), *grant};
}

v1::SessionState Sharing::SendEvents(const v1::SendEventsRequest& request, const grpc::CallbackServerContext& context) {
  const GrantAccess access = Access(context, request.session_id(), request.grant());
  const Grant& grant = access.grant;
  google::protobuf::RepeatedPtrField<v1::SessionEvent> drives;
  const Clock::time_point arrival = Clock::now();
  for (const v1::SessionEvent& event : request.events()) {
    if (!event.has_pointer()) *drives.Add() = event;
  }
  if (!drives.empty() && grant.role != GrantRole::kPresenter) {
    throw RpcError::PermissionDenied(
        fmt::format("events: grant {} is a viewer's; a viewer's only event is its pointer", grant.id));
  }
  if (drives.size() < request.events_size() && !grant.allow_pointer && grant.role != GrantRole::kPresenter) {
    throw RpcError::PermissionDenied(
        fmt::format("pointer: grant {} does not share its holder's pointer (allow_pointer)", grant.id));
  }
  if (!drives.empty()) access.session->OnEvents(drives, arrival, /*from_grant=*/true);
  for (const v1::SessionEvent& event : request.events()) {
    if (event.has_pointer()) access.session->OnPointer(grant.holder(), event.pointer(), arrival);
  }
  return access.session->CurrentState();
}

void Sharing::ExpireGrants() {
  for (const Grant& grant : grants_.TakeExpired()) {
    const std::shared_ptr<Session> session = find_(grant.session_id);
    if (!session) continue;
    if (grant.role == GrantRole::kPresenter) session->SetPresenter(session->owner());
    session->EndWatchers(grant.id, RpcError::PermissionDenied(fmt::format("grant {} expired", grant.id)).status());
  }
}

}  // namespace cinevol::service

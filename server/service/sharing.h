// Sharing a session (docs/sharing.md): the owner's grants, and what a
// grant's holder may do with the session. ServiceCore holds one Sharing; the
// service methods and WatchSession's reactor call it.
#pragma once

#include <grpcpp/server_context.h>

#include <functional>
#include <memory>
#include <string>

#include "cinevol/v1/service.pb.h"
#include "runtime/grants.h"
#include "runtime/principal.h"
#include "runtime/session.h"
#include "service/auth.h"

namespace cinevol::service {

// A grant's holder, checked, and the session it opens.
struct GrantAccess {
  std::shared_ptr<Session> session;
  Grant grant;
};

class Sharing {
 public:
  // `find`: the session with an id, whoever owns it (null when none);
  // `owned`: the same for a caller, checking ownership (ServiceCore::FindSession).
  using FindAny = std::function<std::shared_ptr<Session>(const std::string& id)>;
  using FindOwned = std::function<std::shared_ptr<Session>(const std::string& id, const Principal& caller)>;
  Sharing(const Authenticator& authenticator, int max_grants_per_principal, FindAny find, FindOwned owned);

  v1::Grant Share(const v1::ShareSessionRequest& request, const Principal& caller);
  v1::ListSharesResponse List(const v1::ListSharesRequest& request, const Principal& caller) const;
  v1::RevokeShareResponse Revoke(const v1::RevokeShareRequest& request, const Principal& caller);
  // By the owner (a token) or, with request.grant, the presenter.
  v1::HandOverResponse HandOver(const v1::HandOverRequest& request, const grpc::CallbackServerContext& context);

  // The grant `secret` names, for its holder: a link's secret alone, a
  // principal's grant with that principal's token. PERMISSION_DENIED for a
  // bad, revoked or expired grant, one for another session or principal.
  GrantAccess Access(const grpc::CallbackServerContext& context, const std::string& session_id,
                     const std::string& secret) const;
  // Session `id` for a call its owner (or an operator) or its presenter may
  // make with a token alone (StoreMeasurements): the presenter by a
  // principal's grant, whose token names them (a link's holder has none).
  // NOT_FOUND or PERMISSION_DENIED as ServiceCore::FindSession.
  std::shared_ptr<Session> OwnedOrPresented(const std::string& id, const Principal& caller) const;
  // SendEvents by a grant's holder: a presenter's events as the owner's, a
  // viewer's pointer (where allowed); anything else PERMISSION_DENIED.
  v1::SessionState SendEvents(const v1::SendEventsRequest& request, const grpc::CallbackServerContext& context);

  // Ends the streams of grants past their expiry (the server's sweeper).
  void ExpireGrants();
  // The session ended: its grants go.
  void SessionEnded(const std::string& session_id) { grants_.ForgetSession(session_id); }

 private:
  v1::Grant ToProto(const Grant& grant, const Session* session) const;
  // One presenter at a time: grant `grant_id` presents (empty: the owner,
  // as `presenter`), every other grant of the session views.
  void MakePresenter(Session& session, const std::string& grant_id, const std::string& presenter);

  const Authenticator& authenticator_;
  GrantRegistry grants_;
  FindAny find_;
  FindOwned owned_;
};

}  // namespace cinevol::service

// The servers one Client may use, and what it keeps to use several of them:
// a channel to each, where each of its sessions lives, the state each was
// created in, and how it got each volume. The Client and its streams share
// it (a stream re-creates its session from the stream's reader thread).
//
// Placement: with more than one server, a new session goes to the one that
// says it has the most room (ServerStatus: max_sessions - sessions_held,
// while accepting_sessions); one that is full, unreachable or lacks the
// volume is passed over for the next. Failover: a session whose server went
// away is created again, from its last state, by the same placement among
// the others. A volume the client loaded or uploaded is loaded or uploaded
// again where a session or a volume call names it; one the operator
// preloaded must be there under the same id (every pod of a deployment
// preloads the same).
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cinevol/v1/service.grpc.pb.h"
#include "client_options.h"
#include "session_state.h"
#include "volume_calls.h"

namespace cinevol {

// How the client got a volume, to get it again on another server.
struct VolumeOrigin {
  std::string home;                             // the server whose id it is
  v1::LoadVolumeRequest load;                   // LoadVolume, under the server's data roots (path empty: not loaded)
  v1::LoadSeriesRequest series;                 // LoadSeries, from a PACS (series_uid empty: not loaded)
  std::filesystem::path upload;                 // UploadVolume, a local file
  v1::UploadVolumeChunk::Header upload_fields;  // and its header's fields beyond name and size
  std::string labels_path, labels_table_path;   // LoadLabels
  std::filesystem::path labels_upload, labels_upload_table;  // UploadLabels
};

// Where a session went: its id there, the address its calls go to, and the
// entry of the server list it was placed through.
struct Placement {
  v1::CreateSessionResponse response;
  std::string address;
  std::string server;
};

class ServerPool {
 public:
  // Splits options.address at commas and connects to the first server that
  // answers within connect_timeout; throws RpcError(UNAVAILABLE) naming
  // them all when none does.
  explicit ServerPool(const ClientOptions& options);

  const ClientOptions& options() const { return options_; }
  // The server volume and status calls go to: the first that answered, or
  // the one MoveHome found after it.
  std::string home() const;
  // After `failed` (the home) did not answer: makes another server that
  // answers within connect_timeout the home; false when none does.
  bool MoveHome(const std::string& failed);
  std::shared_ptr<grpc::Channel> Channel(const std::string& address);
  // A context with the token and a deadline of options().call_timeout.
  std::unique_ptr<grpc::ClientContext> CallContext() const { return CallContext(options_.call_timeout); }
  // The same with a deadline of `timeout` from now; nullopt: none.
  std::unique_ptr<grpc::ClientContext> CallContext(std::optional<std::chrono::milliseconds> timeout) const;

  // Volumes the client loaded or uploaded, by their id on origin.home.
  void RememberVolume(const std::string& id, const VolumeOrigin& origin);
  // A segmentation the client gave volume `id` (its id on origin.home).
  void RememberLabels(const std::string& id, const VolumeOrigin& labels);
  // The id volume `id` has on `server`, loading or uploading it there as the
  // client did where it got it (with its segmentation); an operator's volume
  // keeps its id. Throws RpcError.
  std::string VolumeOn(const std::string& server, const std::string& id);
  // The same without getting it there: its id there if the client put it there.
  std::string KnownIdOn(const std::string& server, const std::string& id) const;

  // Places and creates a session (see above) and remembers it.
  Placement CreateSession(const v1::CreateSessionRequest& request);
  // Where calls for session `id` go: the address it was placed at, or
  // home() for a session this client did not create. A session that moved
  // is found by its first id too.
  std::string AddressOf(const std::string& id) const;
  std::string CurrentId(const std::string& id) const;
  void Forget(const std::string& id);

  // What session `id`'s stream tells its SessionState (for a session this
  // client created; others are ignored): an event sent, the server's state,
  // a new stream attached to the same session.
  void Sent(const std::string& id, const v1::SessionEvent& event);
  void Adopt(const std::string& id, const v1::SessionState& state);
  void Reattached(const std::string& id);
  // Whether the client created session `id` and so can re-create it.
  bool CanRelocate(const std::string& id) const;
  // Creates session `id` again from the server's last state, on another
  // server than the one that held it where there is another; `replay` gets
  // the events to send on its new stream (SessionState::Unanswered). Throws
  // RpcError when no server takes it.
  Placement Relocate(const std::string& id, std::vector<v1::SessionEvent>& replay);
  // A grant the client made for session `id` (Client::Share): Relocate
  // restores it, secret and expiry, where the session moves (docs/sharing.md).
  void RememberGrant(const std::string& id, const v1::ShareSessionRequest& request, const v1::Grant& grant);
  // Every server's address, the home first: where a watcher looks for its session.
  std::vector<std::string> Servers() const;

 private:
  struct Route {
    std::string current_id, address, server;
    std::optional<SessionState> state;
    std::vector<v1::ShareSessionRequest> grants = {};  // restore_secret set, expires_seconds: the Unix end
  };
  // Re-makes `grants` on `address` for session `id` there; a grant that has
  // expired or is refused is left behind (its viewers then stop following).
  void RestoreGrants(const std::string& address, const std::string& id,
                     const std::vector<v1::ShareSessionRequest>& grants);
  struct Room {
    std::string server;
    long free = -1;           // sessions it takes, as it said; -1: full, draining or unreachable
    long created_before = 0;  // created_[server] before it was asked
  };

  // The first server but `skip` to answer within connect_timeout; empty: none.
  std::string FirstAnswering(const std::string& skip);
  // The servers' room, as each says; `avoid` with none (tried last: it may be the only one).
  std::vector<Room> ByRoom(const std::string& avoid);
  // Takes the room with the most left out of `rooms` and counts a creation
  // under way on it (placing_). What is left is what the server said, less
  // this client's creations on it under way or done since it was asked, so
  // sessions created at once from many threads spread.
  Room TakeBest(std::vector<Room>& rooms);
  Placement Place(v1::CreateSessionRequest request, const std::string& avoid);

  const ClientOptions options_;
  std::vector<std::string> servers_;
  std::string home_;
  std::shared_ptr<grpc::ChannelCredentials> credentials_;

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<grpc::Channel>> channels_;
  std::map<std::string, VolumeOrigin> volumes_;                        // by id on their origin's home
  std::map<std::pair<std::string, std::string>, std::string> copies_;  // (server, that id) -> id there
  std::map<std::string, std::shared_ptr<Route>> routes_;               // by every id the session had
  std::map<std::string, long> placing_;                                // creations under way, by server
  std::map<std::string, long> created_;                                // creations done, by server
};

}  // namespace cinevol

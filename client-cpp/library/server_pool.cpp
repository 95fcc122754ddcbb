#include "server_pool.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <future>
#include <iterator>
#include <sstream>

#include "pacs_calls.h"

namespace cinevol {
namespace {

constexpr int kMaxReceiveBytes = 512 << 20;  // a 4K EXR snapshot is about 100 MB
// One server's turn while the client looks for one that answers.
constexpr std::chrono::milliseconds kConnectTurn{100};
// How long placement waits for a server's status: a dead one must not hold
// up a session on a live one.
constexpr std::chrono::milliseconds kStatusTimeout{2000};

std::string ReadPem(const std::filesystem::path& file, const char* what) {
  std::ifstream in(file, std::ios::binary);
  if (!in || std::filesystem::is_directory(file)) {
    throw std::invalid_argument(fmt::format("{} {}: cannot read the file", what, file.string()));
  }
  std::string text(std::istreambuf_iterator<char>(in), {});
  if (text.find("-----BEGIN ") == std::string::npos) {
    throw std::invalid_argument(fmt::format("{} {}: not a PEM file", what, file.string()));
  }
  return text;
}

std::shared_ptr<grpc::ChannelCredentials> Credentials(const ClientOptions& options) {
  if (options.tls_ca.empty() && options.tls_cert.empty() && options.tls_key.empty()) {
    return grpc::InsecureChannelCredentials();
  }
  if (options.tls_cert.empty() != options.tls_key.empty()) {
    throw std::invalid_argument("tls_cert (--tls-cert) and tls_key (--tls-key) go together: give both");
  }
  grpc::SslCredentialsOptions ssl;
  if (!options.tls_ca.empty()) ssl.pem_root_certs = ReadPem(options.tls_ca, "--tls-ca");
  if (!options.tls_cert.empty()) {
    ssl.pem_cert_chain = ReadPem(options.tls_cert, "--tls-cert");
    ssl.pem_private_key = ReadPem(options.tls_key, "--tls-key");
  }
  return grpc::SslCredentials(ssl);
}

std::vector<std::string> SplitServers(const std::string& list) {
  std::vector<std::string> servers;
  std::stringstream in(list);
  for (std::string item; std::getline(in, item, ',');) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) servers.push_back(item);
  }
  if (servers.empty()) throw std::invalid_argument("address: no server given");
  return servers;
}

// Whether another server may do what this one could not.
bool TryAnother(grpc::StatusCode code) {
  return code == grpc::StatusCode::RESOURCE_EXHAUSTED || code == grpc::StatusCode::UNAVAILABLE ||
         code == grpc::StatusCode::DEADLINE_EXCEEDED || code == grpc::StatusCode::NOT_FOUND;
}

}  // namespace

ServerPool::ServerPool(const ClientOptions& options)
    : options_(options), servers_(SplitServers(options.address)), credentials_(Credentials(options)) {
  home_ = FirstAnswering({});
  if (!home_.empty()) return;
  const bool tls = !options.tls_ca.empty() || !options.tls_cert.empty();
  throw RpcError({grpc::StatusCode::UNAVAILABLE,
                  fmt::format("cannot reach cinevol-server at {} within {} s{}", options.address,
                              options.connect_timeout.count() / 1000.0,
                              tls ? " (over TLS: is the server's certificate signed by --tls-ca, for this "
                                    "address, and does the server accept the client certificate?)"
                                  : " (is it running? a server with TLS needs --tls-ca)")});
}

std::string ServerPool::FirstAnswering(const std::string& skip) {
  // The servers take turns in short waits, so a dead first one does not use
  // up the time of those after it.
  const auto deadline = std::chrono::system_clock::now() + options_.connect_timeout;
  do {
    for (const std::string& server : servers_) {
      if (server == skip) continue;
      if (Channel(server)->WaitForConnected(std::min(deadline, std::chrono::system_clock::now() + kConnectTurn))) {
        return server;
      }
    }
  } while (std::chrono::system_clock::now() < deadline);
  return {};
}

std::string ServerPool::home() const {
  std::lock_guard lock(mu_);
  return home_;
}

bool ServerPool::MoveHome(const std::string& failed) {
  if (servers_.size() < 2) return false;
  const std::string next = FirstAnswering(failed);
  if (next.empty()) return false;
  std::lock_guard lock(mu_);
  if (home_ == failed) home_ = next;
  return true;
}

std::shared_ptr<grpc::Channel> ServerPool::Channel(const std::string& address) {
  std::lock_guard lock(mu_);
  std::shared_ptr<grpc::Channel>& channel = channels_[address];
  if (!channel) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(kMaxReceiveBytes);
    args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, int(options_.keepalive.count()));
    args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, int(options_.keepalive_timeout.count()));
    args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);  // a stream of a refined session sends nothing for long
    // A Client's connections are its own, not shared with other Clients in
    // the process: a server's limit of streams per connection is then one
    // client's, as it is across machines (loadtest's viewers rely on it).
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
    channel = grpc::CreateCustomChannel(address, credentials_, args);
  }
  return channel;
}

std::unique_ptr<grpc::ClientContext> ServerPool::CallContext(std::optional<std::chrono::milliseconds> timeout) const {
  auto context = std::make_unique<grpc::ClientContext>();
  if (timeout) context->set_deadline(std::chrono::system_clock::now() + *timeout);
  if (!options_.token.empty()) context->AddMetadata("authorization", "Bearer " + options_.token);
  return context;
}

void ServerPool::RememberVolume(const std::string& id, const VolumeOrigin& origin) {
  std::lock_guard lock(mu_);
  volumes_[id] = origin;
}

void ServerPool::RememberLabels(const std::string& id, const VolumeOrigin& labels) {
  std::lock_guard lock(mu_);
  auto [it, operators] = volumes_.try_emplace(id);
  VolumeOrigin& origin = it->second;
  if (operators) origin.home = labels.home;  // the volume was there already: only the labels are the client's
  origin.labels_path = labels.labels_path;
  origin.labels_table_path = labels.labels_table_path;
  origin.labels_upload = labels.labels_upload;
  origin.labels_upload_table = labels.labels_upload_table;
  // Copies elsewhere have the old segmentation: get them again.
  for (auto copy = copies_.begin(); copy != copies_.end();) {
    copy = copy->first.second == id ? copies_.erase(copy) : std::next(copy);
  }
}

std::vector<ServerPool::Room> ServerPool::ByRoom(const std::string& avoid) {
  std::vector<Room> rooms;
  std::vector<std::future<long>> asked;
  for (const std::string& server : servers_) {
    if (server == avoid) continue;
    {
      std::lock_guard lock(mu_);
      rooms.push_back({server, -1, created_[server]});
    }
    asked.push_back(std::async(std::launch::async, [this, server] {
      auto stub = v1::ServerService::NewStub(Channel(server));
      auto context = CallContext();
      context->set_deadline(std::chrono::system_clock::now() + std::min(options_.call_timeout, kStatusTimeout));
      v1::ServerStatus status;
      if (!stub->GetStatus(context.get(), {}, &status).ok() || !status.accepting_sessions()) return -1L;
      return long(status.max_sessions()) - long(status.sessions_held());
    }));
  }
  for (std::size_t i = 0; i < rooms.size(); ++i) rooms[i].free = asked[i].get();
  if (!avoid.empty()) rooms.push_back({avoid});  // with no room known: last
  return rooms;
}

Placement ServerPool::CreateSession(const v1::CreateSessionRequest& request) {
  Placement placed = Place(request, {});
  auto route = std::make_shared<Route>(
      Route{placed.response.session_id(), placed.address, placed.server, SessionState(request, placed.response)});
  std::lock_guard lock(mu_);
  routes_[placed.response.session_id()] = std::move(route);
  return placed;
}

ServerPool::Room ServerPool::TakeBest(std::vector<Room>& rooms) {
  std::lock_guard lock(mu_);
  auto left = [&](const Room& r) {
    return r.free < 0 ? r.free : r.free - placing_[r.server] - (created_[r.server] - r.created_before);
  };
  auto best = rooms.begin();
  for (auto it = rooms.begin(); it != rooms.end(); ++it) {
    if (left(*it) > left(*best)) best = it;  // the first of equals: the list breaks ties
  }
  Room room = *best;
  rooms.erase(best);
  ++placing_[room.server];
  return room;
}

Placement ServerPool::Place(v1::CreateSessionRequest request, const std::string& avoid) {
  const std::string volume_id = request.volume_id();
  std::vector<Room> rooms = servers_.size() == 1 ? std::vector<Room>{{servers_[0]}} : ByRoom(avoid);
  std::vector<std::string> refusals;
  while (!rooms.empty()) {
    const Room room = TakeBest(rooms);
    auto landed = [&](bool created) {
      std::lock_guard lock(mu_);
      --placing_[room.server];
      if (created) ++created_[room.server];
    };
    try {
      request.set_volume_id(VolumeOn(room.server, volume_id));
      Placement placed;
      auto stub = v1::SessionService::NewStub(Channel(room.server));
      Check(stub->CreateSession(CallContext().get(), request, &placed.response));
      placed.server = room.server;
      placed.address = placed.response.address().empty() ? room.server : placed.response.address();
      landed(true);
      return placed;
    } catch (const RpcError& e) {
      landed(false);
      if (!TryAnother(e.code()) || rooms.empty()) {
        if (refusals.empty()) throw;
        refusals.push_back(fmt::format("{}: {}", room.server, e.what()));
        throw RpcError({e.code(), fmt::format("no server took the session: {}", fmt::join(refusals, "; "))});
      }
      refusals.push_back(fmt::format("{}: {}", room.server, e.what()));
    }
  }
  throw RpcError({grpc::StatusCode::UNAVAILABLE, "no server to place the session on"});  // rooms is never empty
}

std::string ServerPool::VolumeOn(const std::string& server, const std::string& id) {
  VolumeOrigin origin;
  {
    std::lock_guard lock(mu_);
    if (auto copy = copies_.find({server, id}); copy != copies_.end()) return copy->second;
    auto it = volumes_.find(id);
    if (it == volumes_.end() || it->second.home == server) return id;  // the operator's: the same id everywhere
    origin = it->second;
  }
  VolumeCalls calls(*this, server);
  std::string there = id;  // where the client gave only labels, the volume is the operator's
  try {
    if (!origin.upload.empty()) {
      there = calls.Upload(origin.upload, origin.upload_fields).id();
    } else if (!origin.load.path().empty()) {
      there = calls.Load(origin.load).id();
    } else if (!origin.series.series_uid().empty()) {
      there = PacsCalls(*this, server).LoadSeries(origin.series).id();
    }
    if (!origin.labels_path.empty()) {
      calls.LoadLabels(there, origin.labels_path, origin.labels_table_path);
    } else if (!origin.labels_upload.empty()) {
      calls.UploadLabels(there, origin.labels_upload, origin.labels_upload_table);
    }
  } catch (const RpcError&) {
    throw;
  } catch (const std::exception& e) {  // a local file gone since it was uploaded
    throw RpcError({grpc::StatusCode::FAILED_PRECONDITION,
                    fmt::format("volume '{}': cannot upload it again to {}: {}", id, server, e.what())});
  }
  std::lock_guard lock(mu_);
  copies_[{server, id}] = there;
  return there;
}

std::string ServerPool::KnownIdOn(const std::string& server, const std::string& id) const {
  std::lock_guard lock(mu_);
  auto copy = copies_.find({server, id});
  return copy == copies_.end() ? id : copy->second;
}

std::string ServerPool::AddressOf(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  return it == routes_.end() ? home_ : it->second->address;
}

std::string ServerPool::CurrentId(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  return it == routes_.end() ? id : it->second->current_id;
}

void ServerPool::Forget(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  if (it == routes_.end()) return;
  const std::shared_ptr<Route> route = it->second;
  for (auto r = routes_.begin(); r != routes_.end();) r = r->second == route ? routes_.erase(r) : std::next(r);
}

void ServerPool::Sent(const std::string& id, const v1::SessionEvent& event) {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  if (it != routes_.end() && it->second->state) it->second->state->Sent(event);
}

void ServerPool::Adopt(const std::string& id, const v1::SessionState& state) {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  if (it != routes_.end() && it->second->state) it->second->state->Adopt(state);
}

void ServerPool::Reattached(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  if (it != routes_.end() && it->second->state) it->second->state->Reattached();
}

bool ServerPool::CanRelocate(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  return it != routes_.end() && it->second->state.has_value();
}

Placement ServerPool::Relocate(const std::string& id, std::vector<v1::SessionEvent>& replay) {
  std::shared_ptr<Route> route;
  v1::CreateSessionRequest request;
  {
    std::lock_guard lock(mu_);
    auto it = routes_.find(id);
    if (it == routes_.end() || !it->second->state) {
      throw RpcError(
          {grpc::StatusCode::FAILED_PRECONDITION, fmt::format("session '{}': not created by this client", id)});
    }
    route = it->second;
    request = route->state->request();
  }
  Placement placed = Place(request, route->server);
  std::vector<v1::ShareSessionRequest> grants;
  {
    std::lock_guard lock(mu_);
    replay = route->state->Unanswered();
    route->state->Recreated();
    route->current_id = placed.response.session_id();
    route->address = placed.address;
    route->server = placed.server;
    routes_[route->current_id] = route;
    grants = route->grants;
  }
  RestoreGrants(placed.address, placed.response.session_id(), grants);
  return placed;
}

void ServerPool::RememberGrant(const std::string& id, const v1::ShareSessionRequest& request, const v1::Grant& grant) {
  std::lock_guard lock(mu_);
  auto it = routes_.find(id);
  if (it == routes_.end()) return;  // not this client's session: it cannot move it either
  v1::ShareSessionRequest kept = request;
  kept.set_restore_secret(grant.secret());
  kept.set_expires_seconds(std::uint32_t(std::max<std::int64_t>(grant.expires_unix_seconds(), 0)));
  it->second->grants.push_back(std::move(kept));
}

void ServerPool::RestoreGrants(const std::string& address, const std::string& id,
                               const std::vector<v1::ShareSessionRequest>& grants) {
  auto stub = v1::SessionService::NewStub(Channel(address));
  const std::int64_t now =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  for (v1::ShareSessionRequest request : grants) {
    const std::int64_t left = std::int64_t(request.expires_seconds()) - now;
    if (left < 1) continue;
    request.set_session_id(id);
    request.set_expires_seconds(std::uint32_t(left));
    v1::Grant restored;
    stub->ShareSession(CallContext().get(), request, &restored);  // refused: its viewers stop following
  }
}

std::vector<std::string> ServerPool::Servers() const {
  std::vector<std::string> out{home()};
  for (const std::string& s : servers_) {
    if (s != out.front()) out.push_back(s);
  }
  return out;
}

}  // namespace cinevol

// Sharing a session (docs/sharing.md), contracts that scripts use:
//   cinevol share SESSION [--principal P | --link] [--role viewer|presenter] [--expires 2h] [--allow-pointer]
//     (prints the grant's secret alone on its last line)
//   cinevol shares SESSION [--json]
//   cinevol revoke SESSION GRANT_ID
//   cinevol handover SESSION [GRANT_ID]
//   cinevol watch --server ADDR --grant G [--seconds S] --out DIR   (frames and frames.csv as `play` writes them)
#include <fmt/chrono.h>
#include <fmt/format.h>

#include <chrono>
#include <thread>

#include "commands.h"
#include "connection_options.h"
#include "frame_recorder.h"
#include "sharing_calls.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct ShareOptions {
  ConnectionOptions connection;
  std::string session, principal, role = "viewer", expires, grant_id;
  bool link = false, allow_pointer = false, json = false;
};

// "90s", "15m", "2h", "1d" or plain seconds; InputError otherwise.
std::uint32_t ParseDuration(const std::string& text) {
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  const std::string unit = text.substr(used);
  const double scale = unit.empty() || unit == "s" ? 1
                       : unit == "m"               ? 60
                       : unit == "h"               ? 3600
                       : unit == "d"               ? 86400
                                                   : 0;
  if (used == 0 || scale == 0 || !(value > 0) || value * scale > 7 * 86400) {
    throw InputError(fmt::format("--expires '{}': give a time up to a week such as 90s, 15m, 2h or 1d", text));
  }
  return std::uint32_t(value * scale + 0.5);
}

std::string ExpiresText(std::int64_t unix_seconds) {
  return fmt::format("{:%Y-%m-%d %H:%M:%S} UTC", fmt::gmtime(std::time_t(unix_seconds)));
}

std::string Holder(const v1::Grant& g) { return g.principal().empty() ? "link" : g.principal(); }

void RunShare(const ShareOptions& o) {
  if (o.link == !o.principal.empty()) throw InputError("share: give --principal P or --link (one of them)");
  v1::ShareSessionRequest request;
  request.set_session_id(o.session);
  request.set_principal(o.principal);
  request.set_role(o.role == "presenter" ? v1::PRESENTER : v1::VIEWER);
  request.set_allow_pointer(o.allow_pointer);
  if (!o.expires.empty()) request.set_expires_seconds(ParseDuration(o.expires));
  const v1::Grant grant = Connect(o.connection).Share(request);
  fmt::print("grant {} for {}: {}, expires {}{}\n", grant.id(), Holder(grant), o.role,
             ExpiresText(grant.expires_unix_seconds()), grant.allow_pointer() ? ", pointer shared" : "");
  fmt::print("watch: cinevol watch --server {} --grant <the line below>{} --out DIR\n", o.connection.server,
             grant.principal().empty() ? "" : " --token <" + grant.principal() + "'s token>");
  fmt::print("{}\n", grant.secret());  // alone on the last line: scripts take it from there
}

void RunShares(const ShareOptions& o) {
  const std::vector<v1::Grant> grants = Connect(o.connection).ListShares(o.session);
  if (o.json) {
    v1::ListSharesResponse response;
    for (const v1::Grant& g : grants) *response.add_grants() = g;
    return PrintJson(response);
  }
  if (grants.empty()) return fmt::print("session {} is not shared\n", o.session);
  std::vector<TextRow> rows{{"GRANT", "FOR", "ROLE", "EXPIRES", "WATCHING", "POINTER"}};
  for (const v1::Grant& g : grants) {
    rows.push_back({g.id(), Holder(g), g.role() == v1::PRESENTER ? "presenter" : "viewer",
                    ExpiresText(g.expires_unix_seconds()), std::to_string(g.watching()),
                    g.allow_pointer() ? "yes" : "no"});
  }
  PrintTable(rows);
}

void RunRevoke(const ShareOptions& o) {
  const std::uint32_t ended = Connect(o.connection).RevokeShare(o.session, o.grant_id);
  fmt::print("revoked {}: {} stream{} ended\n", o.grant_id, ended, ended == 1 ? "" : "s");
}

void RunHandOver(const ShareOptions& o) {
  v1::HandOverRequest request;
  request.set_session_id(o.session);
  request.set_grant_id(o.grant_id);
  fmt::print("{} presents session {}\n", Connect(o.connection).HandOver(request), o.session);
}

struct WatchOptions {
  ConnectionOptions connection;
  std::string grant, out;
  double seconds = 10;
};

void RunWatch(const WatchOptions& o) {
  Client client = Connect(o.connection);
  const std::unique_ptr<SessionWatch> watch = client.Watch(o.grant);
  FrameRecorder recorder(o.out);
  const auto start = std::chrono::steady_clock::now();
  const auto end = start + std::chrono::duration<double>(o.seconds);
  std::uint64_t frames = 0;
  std::string presenter;
  while (std::chrono::steady_clock::now() < end) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
    const std::optional<v1::ServerMessage> message = watch->Next(std::min(left, std::chrono::milliseconds(500)));
    if (!message) {
      if (watch->ended()) break;
      continue;
    }
    if (message->has_state()) presenter = message->state().presenter();
    if (message->has_notice()) fmt::print("notice: {}\n", message->notice().message());
    if (!message->has_frame()) continue;
    ++frames;
    recorder.Add({message->frame(), std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()});
  }
  // Ended by the server (revoked, expired, the session gone) before the time was up: its words, exit 1.
  const grpc::Status status = watch->ended() ? watch->status() : grpc::Status::OK;
  watch->Cancel();
  fmt::print("watched {} presenting for {:.1f} s: {} frames into {}\n", presenter.empty() ? "?" : presenter,
             std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), frames,
             recorder.csv_path().string());
  Check(status);
}

}  // namespace

void AddShareCommands(CLI::App& app) {
  auto o = std::make_shared<ShareOptions>();
  auto* share = app.add_subcommand("share", "Share a session: a grant for a principal or a link (docs/sharing.md)");
  AddConnectionOptions(share, o->connection);
  share->add_option("session", o->session, "The session's id")->required();
  auto* principal = share->add_option("--principal", o->principal, "Who may watch: their own token signs them in");
  share->add_flag("--link", o->link, "A link instead: its secret alone lets its holder watch")->excludes(principal);
  share->add_option("--role", o->role, "viewer (watches) or presenter (drives)")
      ->check(CLI::IsMember({"viewer", "presenter"}))
      ->capture_default_str();
  share->add_option("--expires", o->expires, "How long the grant lasts: 90s, 15m, 2h, 1d (default 2h, at most 7d)");
  share->add_flag("--allow-pointer", o->allow_pointer, "A viewer's pointer is shown to everyone");
  share->callback([o] { RunShare(*o); });

  auto* shares = app.add_subcommand("shares", "A session's grants (no secrets), with the streams watching by each");
  AddConnectionOptions(shares, o->connection);
  shares->add_option("session", o->session, "The session's id")->required();
  shares->add_flag("--json", o->json, "Print ListShares' answer as proto3 JSON");
  shares->callback([o] { RunShares(*o); });

  auto* revoke = app.add_subcommand("revoke", "Revoke a grant: its streams end at once");
  AddConnectionOptions(revoke, o->connection);
  revoke->add_option("session", o->session, "The session's id")->required();
  revoke->add_option("grant", o->grant_id, "The grant's id (gXXXX, as `cinevol shares` lists it)")->required();
  revoke->callback([o] { RunRevoke(*o); });

  auto* handover = app.add_subcommand("handover", "Hand the presenter role to a grant, or (no grant) take it back");
  AddConnectionOptions(handover, o->connection);
  handover->add_option("session", o->session, "The session's id")->required();
  handover->add_option("grant", o->grant_id, "The grant that presents from now on; none: the owner");
  handover->callback([o] { RunHandOver(*o); });

  auto w = std::make_shared<WatchOptions>();
  auto* watch = app.add_subcommand("watch", "Watch a shared session by its grant; frames and frames.csv as play");
  AddConnectionOptions(watch, w->connection);
  watch->add_option("--grant", w->grant, "The grant's secret (cvg_...), as `cinevol share` printed it")->required();
  watch->add_option("--seconds", w->seconds, "How long to watch")
      ->check(CLI::Range(0.1, 86400.0))
      ->capture_default_str();
  watch->add_option("--out", w->out, "Folder for frames/ and frames.csv")->required();
  watch->callback([w] { RunWatch(*w); });
}

}  // namespace cinevol::cli

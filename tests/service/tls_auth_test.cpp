// TLS, mutual TLS and bearer tokens: certificates made with the `openssl`
// command at test time (a CA, a server certificate for 127.0.0.1/localhost,
// clients alice and bob, and a stranger from another CA), real servers on
// loopback, the token file's format and its reload on SIGHUP, what answers
// without a token (health) and what does not (reflection, two tokens at
// once), and the listen policy that keeps an unauthenticated server on
// loopback.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <google/protobuf/descriptor.pb.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "core/error.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "server_process.h"
#include "service/auth.h"
#include "runtime/errors.h"
#include "service/tls.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The certificates, made once for the suite.
class Pki {
 public:
  static const Pki* Get() {
    static const Pki* pki = [] {
      auto* made = new Pki;
      if (!made->Make()) {
        delete made;
        return static_cast<Pki*>(nullptr);
      }
      return made;
    }();
    return pki;
  }
  static std::string why_not;  // when Get() is null
  static fs::path made_in;      // the folder Get() made, removed at the end

  fs::path dir;
  fs::path ca() const { return dir / "ca.pem"; }
  fs::path server_cert() const { return dir / "server.pem"; }
  fs::path server_key() const { return dir / "server.key"; }
  fs::path cert(const std::string& who) const { return dir / (who + ".pem"); }
  fs::path key(const std::string& who) const { return dir / (who + ".key"); }

 private:
  bool Run(const std::string& command) {
    const std::string line = "cd '" + dir.string() + "' && " + command + " >> openssl.log 2>&1";
    if (std::system(line.c_str()) == 0) return true;
    std::ifstream in(dir / "openssl.log");
    why_not = "openssl failed: " + command + "\n" + std::string(std::istreambuf_iterator<char>(in), {});
    return false;
  }

  bool MakeCa(const std::string& name) {
    return Run("openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 3 -subj /CN=" +
               name + " -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign" +
               " -keyout " + name + ".key -out " + name + ".pem");
  }

  // A key and a certificate for `cn`, signed by CA `ca`, with extensions from `ext`.
  bool MakeLeaf(const std::string& who, const std::string& cn, const std::string& ca, const std::string& ext,
                int serial) {
    std::ofstream(dir / (who + ".ext")) << ext << "\n";
    return Run("openssl req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj /CN=" + cn + " -keyout " +
               who + ".key -out " + who + ".csr") &&
           Run("openssl x509 -req -days 3 -in " + who + ".csr -CA " + ca + ".pem -CAkey " + ca + ".key -set_serial " +
               std::to_string(serial) + " -extfile " + who + ".ext -out " + who + ".pem");
  }

  bool Make() {
    if (std::system("openssl version > /dev/null 2>&1") != 0) {
      why_not = "the `openssl` command is not installed: the TLS tests need it to make certificates";
      return false;
    }
    dir = fs::temp_directory_path() / ("cinevol-tls-pki-" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    made_in = dir;
    const std::string client = "basicConstraints=CA:FALSE\nextendedKeyUsage=clientAuth";
    return MakeCa("ca") && MakeCa("otherca") &&
           MakeLeaf("server", "localhost", "ca",
                    "basicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth\nsubjectAltName=IP:127.0.0.1,DNS:localhost",
                    1) &&
           MakeLeaf("alice", "alice", "ca", client, 2) && MakeLeaf("bob", "bob", "ca", client, 3) &&
           MakeLeaf("stranger", "alice", "otherca", client, 4);  // claims to be alice, from another CA
  }
};
std::string Pki::why_not;
fs::path Pki::made_in;

#define REQUIRE_PKI()                                  \
  const Pki* pki = Pki::Get();                         \
  if (pki == nullptr) GTEST_SKIP() << Pki::why_not;

class PkiCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    if (!Pki::made_in.empty()) fs::remove_all(Pki::made_in);
  }
};
[[maybe_unused]] auto* const cleanup = ::testing::AddGlobalTestEnvironment(new PkiCleanup);

ClientOptions Options(const ServerProcess& server, const fs::path& ca = {}, const std::string& who = {},
                      const Pki* pki = nullptr) {
  ClientOptions o;
  o.address = server.address();
  o.connect_timeout = 3s;
  o.call_timeout = 10s;
  o.tls_ca = ca;
  if (!who.empty()) {
    o.tls_cert = pki->cert(who);
    o.tls_key = pki->key(who);
  }
  return o;
}

// The code of the first failure of connecting and listing volumes (OK: both worked).
grpc::StatusCode ConnectAndList(const ClientOptions& options) {
  try {
    Client client(options);
    client.ListVolumes();
    return grpc::StatusCode::OK;
  } catch (const RpcError& e) {
    return e.code();
  }
}

template <class F>
void ExpectRpcError(F&& call, grpc::StatusCode code) {
  try {
    call();
    ADD_FAILURE() << "no error; expected " << StatusCodeName(code);
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), code) << e.what();
  }
}

void WriteFileAtomically(const fs::path& file, const std::string& text) {
  const fs::path temporary = file.string() + ".new";
  std::ofstream(temporary) << text;
  fs::rename(temporary, file);
}

std::pair<int, std::string> RunServer(const ScratchDir& scratch, std::vector<std::string> args) {
  for (const char* a : {"--backend", "cpu", "--volume", "phantom:cube?size=8"}) args.push_back(a);
  return RunProgram(ServerPath(), args, scratch / "refused.log", 60s);
}

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(TlsAuth, TlsServerAnswersClientsThatTrustItsCa) {
  REQUIRE_PKI();
  ScratchDir scratch;
  ServerProcess server(scratch.path(),
                       {"--tls-cert", pki->server_cert().string(), "--tls-key", pki->server_key().string()});
  ASSERT_TRUE(server.running()) << server.Log();

  Client client(Options(server, pki->ca()));
  EXPECT_FALSE(client.ListVolumes().empty());
  EXPECT_GE(client.Status().uptime_seconds(), 0);
  ClientOptions by_name = Options(server, pki->ca());
  by_name.address = "localhost:" + std::to_string(server.port());
  EXPECT_EQ(ConnectAndList(by_name), grpc::StatusCode::OK) << "the certificate names DNS:localhost";

  EXPECT_EQ(ConnectAndList(Options(server)), grpc::StatusCode::UNAVAILABLE) << "a plaintext client";
  EXPECT_EQ(ConnectAndList(Options(server, pki->dir / "otherca.pem")), grpc::StatusCode::UNAVAILABLE)
      << "a client that trusts another CA";

  ClientOptions unreadable = Options(server, scratch / "no-such-ca.pem");
  try {
    Client c(unreadable);
    ADD_FAILURE() << "an unreadable tls_ca was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_TRUE(Contains(e.what(), "no-such-ca.pem")) << e.what();
  }
  EXPECT_TRUE(server.running()) << server.Log();
}

TEST(TlsAuth, MutualTlsNamesTheCallerByCertificate) {
  REQUIRE_PKI();
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--tls-cert", pki->server_cert().string(), "--tls-key",
                                        pki->server_key().string(), "--tls-client-ca", pki->ca().string()});
  ASSERT_TRUE(server.running()) << server.Log();

  EXPECT_EQ(ConnectAndList(Options(server, pki->ca())), grpc::StatusCode::UNAVAILABLE) << "no client certificate";
  EXPECT_EQ(ConnectAndList(Options(server, pki->ca(), "stranger", pki)), grpc::StatusCode::UNAVAILABLE)
      << "a client certificate from another CA";
  EXPECT_EQ(ConnectAndList(Options(server)), grpc::StatusCode::UNAVAILABLE) << "plaintext";

  Client alice(Options(server, pki->ca(), "alice", pki));
  Client bob(Options(server, pki->ca(), "bob", pki));
  const std::string id = alice.CreateSession(SmallSession()).session_id();
  ExpectRpcError([&] { bob.CloseSession(id); }, grpc::StatusCode::PERMISSION_DENIED);
  StreamOptions no_resume;
  no_resume.resume = false;
  auto stream = bob.Attach(id, no_resume);
  EXPECT_FALSE(stream->Next(10s).has_value());
  EXPECT_TRUE(stream->ended());
  EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::PERMISSION_DENIED) << stream->status().error_message();
  alice.CloseSession(id);  // her own: allowed
}

TEST(TlsAuth, MutualTlsWithTokensNeedsBothAndTheTokenNamesTheCaller) {
  REQUIRE_PKI();
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "token-carol carol\ntoken-dave dave\n";
  ServerProcess server(scratch.path(),
                       {"--tls-cert", pki->server_cert().string(), "--tls-key", pki->server_key().string(),
                        "--tls-client-ca", pki->ca().string(), "--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();

  ClientOptions no_token = Options(server, pki->ca(), "alice", pki);
  EXPECT_EQ(ConnectAndList(no_token), grpc::StatusCode::UNAUTHENTICATED) << "a certificate but no token";
  ClientOptions no_cert = Options(server, pki->ca());
  no_cert.token = "token-carol";
  EXPECT_EQ(ConnectAndList(no_cert), grpc::StatusCode::UNAVAILABLE) << "a token but no certificate";

  ClientOptions carol_options = Options(server, pki->ca(), "alice", pki);
  carol_options.token = "token-carol";
  ClientOptions dave_options = Options(server, pki->ca(), "alice", pki);  // the same certificate
  dave_options.token = "token-dave";
  Client carol(carol_options), dave(dave_options);
  const std::string id = carol.CreateSession(SmallSession()).session_id();
  ExpectRpcError([&] { dave.CloseSession(id); }, grpc::StatusCode::PERMISSION_DENIED);
  carol.CloseSession(id);
}

TEST(TlsAuth, SighupReloadsTheTokenFile) {
  ScratchDir scratch;
  const fs::path tokens = scratch / "tokens";
  WriteFileAtomically(tokens, "# who may call\ntoken-one alice\n");
  ServerProcess server(scratch.path(), {"--auth-tokens", tokens.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  auto code = [&](const std::string& token) {
    ClientOptions o = Options(server);
    o.token = token;
    return ConnectAndList(o);
  };
  EXPECT_EQ(code("token-one"), grpc::StatusCode::OK);
  EXPECT_EQ(code("token-two"), grpc::StatusCode::UNAUTHENTICATED);

  WriteFileAtomically(tokens, "token-two bob operator\n");
  ASSERT_EQ(kill(server.pid(), SIGHUP), 0);
  EXPECT_TRUE(Eventually([&] { return code("token-two") == grpc::StatusCode::OK; }, 10s)) << server.Log();
  EXPECT_EQ(code("token-one"), grpc::StatusCode::UNAUTHENTICATED) << "a removed token still works";

  // A bad file: the server says which line and keeps the tokens it had.
  WriteFileAtomically(tokens, "token-three carol\ntoken-four\n");
  ASSERT_EQ(kill(server.pid(), SIGHUP), 0);
  EXPECT_TRUE(Eventually([&] { return Contains(server.Log(), "line 2"); }, 10s)) << server.Log();
  EXPECT_EQ(code("token-two"), grpc::StatusCode::OK);
  EXPECT_EQ(code("token-three"), grpc::StatusCode::UNAUTHENTICATED);

  ASSERT_TRUE(server.running());
  const std::string log = server.Log();
  for (const char* token : {"token-one", "token-two", "token-three", "token-four"}) {
    EXPECT_FALSE(Contains(log, token)) << "the log shows a token:\n" << log;
  }
  EXPECT_EQ(kill(server.pid(), 0), 0) << "SIGHUP ended the server";
}

TEST(TlsAuth, TokenFileFormat) {
  using service::Authenticator;
  ScratchDir scratch;
  const fs::path file = scratch / "tokens";
  std::ofstream(file) << "# comment\n\n  tok-a alice\ntok-op root operator\n";
  Authenticator auth(file);
  EXPECT_TRUE(auth.has_tokens());
  EXPECT_EQ(auth.token_count(), 2u);
  auto as = [&](const std::string& header) { return auth.Authenticate(nullptr, &header); };
  EXPECT_EQ(as("Bearer tok-a").name, "alice");
  EXPECT_FALSE(as("Bearer tok-a").is_operator);
  EXPECT_EQ(as("Bearer tok-op").name, "root");
  EXPECT_TRUE(as("Bearer tok-op").is_operator);
  for (const std::string bad : {"Bearer tok-b", "Bearer tok-", "Bearer tok-a ", "tok-a", "Bearer ", ""}) {
    try {
      as(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const service::RpcError& e) {
      EXPECT_EQ(e.code(), grpc::StatusCode::UNAUTHENTICATED);
    }
  }
  try {
    auth.Authenticate(nullptr, nullptr);
    ADD_FAILURE() << "accepted a call without a token";
  } catch (const service::RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAUTHENTICATED);
  }

  const Authenticator open;
  EXPECT_EQ(open.Authenticate(nullptr, nullptr).name, "anonymous");
  EXPECT_FALSE(open.Authenticate(nullptr, nullptr).is_operator);

  auto error_of = [&](const std::string& text) -> std::string {
    std::ofstream(scratch / "bad") << text;
    try {
      Authenticator bad(scratch / "bad");
      return "";
    } catch (const InputError& e) {
      return e.what();
    }
  };
  EXPECT_TRUE(Contains(error_of("a alice\n# x\nb bob admin\n"), "line 3")) << error_of("a alice\n# x\nb bob admin\n");
  EXPECT_TRUE(Contains(error_of("a alice operator extra\n"), "line 1"));
  EXPECT_TRUE(Contains(error_of("a alice\nlonely\n"), "line 2"));
  EXPECT_TRUE(Contains(error_of("a alice\nb bob\na carol\n"), "line 3"));  // the same token twice
  EXPECT_TRUE(Contains(error_of("# nothing\n"), "no tokens"));
  try {
    Authenticator missing(scratch / "missing");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_TRUE(Contains(e.what(), "--auth-tokens")) << e.what();
  }

  // Reload: the new set, or on error the old one stays.
  std::ofstream(file) << "tok-new nora\n";
  auth.Reload();
  EXPECT_EQ(as("Bearer tok-new").name, "nora");
  EXPECT_THROW(as("Bearer tok-a"), service::RpcError);
  std::ofstream(file) << "tok-newer\n";
  EXPECT_THROW(auth.Reload(), InputError);
  EXPECT_EQ(as("Bearer tok-new").name, "nora");
  std::ofstream(file) << "tok-newest nina\n";
  EXPECT_TRUE(service::ReloadAllTokenFiles());
  EXPECT_EQ(as("Bearer tok-newest").name, "nina");
}

TEST(TlsAuth, ListenPolicyKeepsUnauthenticatedServersOnLoopback) {
  using service::CheckListenPolicy;
  try {
    CheckListenPolicy("0.0.0.0:50051", false, false, false);
    ADD_FAILURE() << "0.0.0.0 without authentication was allowed";
  } catch (const InputError& e) {
    for (const char* flag : {"--auth-tokens", "--tls-cert", "--tls-key", "--tls-client-ca", "--insecure-no-auth"}) {
      EXPECT_TRUE(Contains(e.what(), flag)) << flag << ": " << e.what();
    }
  }
  for (const char* open : {"0.0.0.0:50051", "[::]:50051", ":50051", "10.1.2.3:50051", "example.com:443",
                           "[::ffff:10.0.0.1]:1", "ipv4:192.168.1.1:50051", "128.0.0.1:1"}) {
    EXPECT_THROW(CheckListenPolicy(open, false, false, false), InputError) << open;
    EXPECT_NO_THROW(CheckListenPolicy(open, true, false, false)) << open << " with tokens";
    EXPECT_NO_THROW(CheckListenPolicy(open, false, true, false)) << open << " with mutual TLS";
    EXPECT_NO_THROW(CheckListenPolicy(open, false, false, true)) << open << " with --insecure-no-auth";
    EXPECT_FALSE(service::IsLoopbackListen(open)) << open;
  }
  for (const char* loopback : {"127.0.0.1:50051", "127.0.0.1:0", "127.1.2.3:9", "[::1]:50051", "localhost:50051",
                               "LocalHost:1", "[::ffff:127.0.0.1]:1", "ipv4:127.0.0.1:5", "ipv6:[::1]:5",
                               "unix:/tmp/cinevol.sock"}) {
    EXPECT_NO_THROW(CheckListenPolicy(loopback, false, false, false)) << loopback;
    EXPECT_TRUE(service::IsLoopbackListen(loopback)) << loopback;
  }
}

TEST(TlsAuth, ServerRefusesToStartOpenBeyondLoopbackOrWithBadTlsFiles) {
  ScratchDir scratch;
  auto [code, out] = RunServer(scratch, {"--listen", "0.0.0.0:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--auth-tokens")) << out;
  EXPECT_TRUE(Contains(out, "--insecure-no-auth")) << out;

  std::tie(code, out) = RunServer(scratch, {"--tls-cert", (scratch / "missing.pem").string(), "--tls-key",
                                            (scratch / "missing.key").string(), "--listen", "127.0.0.1:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-cert")) << out;
  std::ofstream(scratch / "garbage.pem") << "not a certificate\n";
  std::tie(code, out) = RunServer(scratch, {"--tls-cert", (scratch / "garbage.pem").string(), "--tls-key",
                                            (scratch / "garbage.pem").string(), "--listen", "127.0.0.1:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-cert")) << out;

  REQUIRE_PKI();
  std::tie(code, out) = RunServer(scratch, {"--tls-cert", pki->server_cert().string(), "--listen", "127.0.0.1:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-key")) << out;
  std::tie(code, out) = RunServer(scratch, {"--tls-cert", pki->server_cert().string(), "--tls-key",
                                            pki->key("alice").string(), "--listen", "127.0.0.1:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-key")) << out;
  std::tie(code, out) =
      RunServer(scratch, {"--tls-cert", pki->server_cert().string(), "--tls-key", pki->server_key().string(),
                          "--tls-client-ca", (scratch / "garbage.pem").string(), "--listen", "127.0.0.1:0"});
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-client-ca")) << out;
}

// Reflection answers only callers the server authenticates (it lists every
// method); health answers anyone (probes carry no token) and tells only
// SERVING or not; a call with two authorization headers (two principals'
// tokens, or one twice) is refused, whichever call it is.
TEST(TlsAuth, ReflectionNeedsATokenHealthDoesNotAndTwoTokensAreRefused) {
  ScratchDir scratch;
  std::ofstream(scratch / "tokens") << "token-alice alice\ntoken-bob bob\n";
  ServerProcess server(scratch.path(), {"--auth-tokens", (scratch / "tokens").string()});
  ASSERT_TRUE(server.running()) << server.Log();
  const auto channel = grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());
  auto with_tokens = [](grpc::ClientContext& context, const std::vector<std::string>& tokens) {
    context.set_deadline(std::chrono::system_clock::now() + 10s);
    for (const std::string& t : tokens) context.AddMetadata("authorization", "Bearer " + t);
  };

  auto health = grpc::health::v1::Health::NewStub(channel);
  for (const char* service : {"", "cinevol.v1.SessionService"}) {
    grpc::ClientContext context;
    with_tokens(context, {});
    grpc::health::v1::HealthCheckRequest request;
    request.set_service(service);
    grpc::health::v1::HealthCheckResponse response;
    const grpc::Status status = health->Check(&context, request, &response);
    ASSERT_TRUE(status.ok()) << "'" << service << "': " << status.error_message();
    EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING) << service;
  }

  namespace reflection = grpc::reflection::v1alpha;
  auto reflection_stub = reflection::ServerReflection::NewStub(channel);
  // One request on a new reflection stream: the call's status, and its answer in `response`.
  auto ask = [&](const std::vector<std::string>& tokens, const reflection::ServerReflectionRequest& request,
                 reflection::ServerReflectionResponse& response) {
    grpc::ClientContext context;
    with_tokens(context, tokens);
    auto stream = reflection_stub->ServerReflectionInfo(&context);
    stream->Write(request);
    stream->WritesDone();
    const bool answered = stream->Read(&response);
    for (reflection::ServerReflectionResponse extra; stream->Read(&extra);) ADD_FAILURE() << "a second answer";
    const grpc::Status status = stream->Finish();
    return status.ok() && !answered ? grpc::Status(grpc::StatusCode::UNKNOWN, "no answer") : status;
  };
  reflection::ServerReflectionRequest list;
  list.set_list_services("");
  reflection::ServerReflectionResponse response;
  EXPECT_EQ(ask({}, list, response).error_code(), grpc::StatusCode::UNAUTHENTICATED) << "no token";
  EXPECT_EQ(ask({"token-mallory"}, list, response).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(ask({"token-alice", "token-bob"}, list, response).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  const grpc::Status listed = ask({"token-alice"}, list, response);
  ASSERT_TRUE(listed.ok()) << listed.error_message();
  std::vector<std::string> names;
  for (const auto& service : response.list_services_response().service()) names.push_back(service.name());
  for (const char* name : {"cinevol.v1.VolumeService", "cinevol.v1.SessionService", "cinevol.v1.ServerService",
                           "grpc.health.v1.Health", "grpc.reflection.v1alpha.ServerReflection"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }

  // Describing a service gives its file first, then the files it imports.
  reflection::ServerReflectionRequest describe;
  describe.set_file_containing_symbol("cinevol.v1.SessionService");
  ASSERT_TRUE(ask({"token-bob"}, describe, response).ok());
  std::vector<std::string> files;
  bool creates = false;
  for (const std::string& bytes : response.file_descriptor_response().file_descriptor_proto()) {
    google::protobuf::FileDescriptorProto file;
    ASSERT_TRUE(file.ParseFromString(bytes));
    files.push_back(file.name());
    for (const auto& service : file.service()) {
      for (const auto& method : service.method())
        creates |= service.name() == "SessionService" && method.name() == "CreateSession";
    }
  }
  ASSERT_FALSE(files.empty());
  EXPECT_EQ(files.front(), "cinevol/v1/service.proto");
  EXPECT_NE(std::find(files.begin(), files.end(), "cinevol/v1/scene.proto"), files.end());
  EXPECT_TRUE(creates);
  describe.set_file_containing_symbol("grpc.health.v1.Health");
  ASSERT_TRUE(ask({"token-bob"}, describe, response).ok());
  EXPECT_EQ(response.file_descriptor_response().file_descriptor_proto_size(), 1);
  describe.set_file_containing_symbol("cinevol.v1.NoSuchThing");
  ASSERT_TRUE(ask({"token-bob"}, describe, response).ok());
  EXPECT_EQ(response.error_response().error_code(), int(grpc::StatusCode::NOT_FOUND));

  // Two authorization headers, on unary calls answered at once and from a pool alike.
  auto server_stub = v1::ServerService::NewStub(channel);
  auto session_stub = v1::SessionService::NewStub(channel);
  for (const std::vector<std::string>& tokens : {std::vector<std::string>{"token-alice", "token-bob"},
                                                 std::vector<std::string>{"token-alice", "token-alice"},
                                                 std::vector<std::string>{"token-alice"}}) {
    const bool one = tokens.size() == 1;
    grpc::ClientContext status_context;
    with_tokens(status_context, tokens);
    v1::ServerStatus server_status;
    const grpc::Status got = server_stub->GetStatus(&status_context, v1::GetStatusRequest(), &server_status);
    EXPECT_EQ(got.error_code(), one ? grpc::StatusCode::OK : grpc::StatusCode::UNAUTHENTICATED) << got.error_message();
    if (!one) {
      EXPECT_TRUE(Contains(got.error_message(), "authorization")) << got.error_message();
    }
    grpc::ClientContext create_context;
    with_tokens(create_context, tokens);
    v1::CreateSessionResponse created;
    const grpc::Status create = session_stub->CreateSession(&create_context, SmallSession(), &created);
    EXPECT_EQ(create.error_code(), one ? grpc::StatusCode::OK : grpc::StatusCode::UNAUTHENTICATED)
        << create.error_message();
  }
}

TEST(TlsAuth, CliConnectsOverMutualTls) {
  REQUIRE_PKI();
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--tls-cert", pki->server_cert().string(), "--tls-key",
                                        pki->server_key().string(), "--tls-client-ca", pki->ca().string()});
  ASSERT_TRUE(server.running()) << server.Log();
  const std::string png = (scratch / "still.png").string();
  auto [code, out] = RunProgram(CliPath(),
                                {"snapshot", "--server", server.address(), "--tls-ca", pki->ca().string(),
                                 "--tls-cert", pki->cert("bob").string(), "--tls-key", pki->key("bob").string(),
                                 "--width", "32", "--height", "24", "--spp", "4", "--out", png},
                                scratch / "cli.log", 60s);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(fs::exists(png)) << out;

  std::tie(code, out) = RunProgram(CliPath(),
                                   {"snapshot", "--server", server.address(), "--tls-ca", pki->ca().string(),
                                    "--connect-timeout", "2", "--out", png},
                                   scratch / "cli.log", 60s);
  EXPECT_EQ(code, 3) << "no client certificate: " << out;
  std::tie(code, out) = RunProgram(CliPath(),
                                   {"snapshot", "--server", server.address(), "--tls-ca",
                                    (scratch / "missing-ca.pem").string(), "--out", png},
                                   scratch / "cli.log", 60s);
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(Contains(out, "--tls-ca")) << out;
  for (const char* command : {"play", "snapshot", "loadtest"}) {
    std::tie(code, out) = RunProgram(CliPath(), {command, "--help"}, scratch / "cli.log", 60s);
    for (const char* flag : {"--tls-ca", "--tls-cert", "--tls-key"}) {
      EXPECT_TRUE(Contains(out, flag)) << command << " lacks " << flag;
    }
  }
}

}  // namespace
}  // namespace cinevol::testing

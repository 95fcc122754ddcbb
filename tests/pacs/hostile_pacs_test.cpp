// The DICOMweb client against PACS that misbehave, played by a tiny HTTP
// server on 127.0.0.1 (loopback_http_server.h): redirects, error statuses,
// malformed or oversized bodies, answers that never come. Each must end in a
// clear error in bounded time, with nothing fetched that should not be.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "core/error.h"
#include "pacs/dicom_json.h"
#include "pacs/dicomweb_client.h"
#include "pacs/loopback_http_server.h"
#include "pacs/pacs_error.h"
#include "support/error_of.h"
#include "support/test_paths.h"

namespace cinevol::pacs {
namespace {

using cinevol::testing::Answer;
using cinevol::testing::ErrorOf;
using cinevol::testing::HttpAnswer;
using cinevol::testing::HttpRequestSeen;
using cinevol::testing::LoopbackHttpServer;
using Clock = std::chrono::steady_clock;

constexpr const char* kStudy = "1.2.3";
constexpr const char* kSeries = "4.5.6";
constexpr const char* kSeriesPath = "/dicom-web/studies/1.2.3/series/4.5.6/instances";
constexpr const char* kBoundary = "XyZ-boundary";

bool StartsWith(const std::string& text, const std::string& prefix) { return text.rfind(prefix, 0) == 0; }

// A minimal DICOM Part 10 look-alike: the preamble, "DICM", a few bytes of `i`.
std::string FakeInstance(int i) { return std::string(128, '\0') + "DICM" + std::string(64, char('a' + i % 26)); }

std::string MultipartHead(std::size_t length) {
  return "HTTP/1.1 200 OK\r\nContent-Type: multipart/related; type=\"application/dicom\"; boundary=" +
         std::string(kBoundary) + "\r\nContent-Length: " + std::to_string(length) + "\r\nConnection: close\r\n\r\n";
}

HttpAnswer InstanceAnswer(const std::string& multipart_body) {
  return {MultipartHead(multipart_body.size()), multipart_body};
}

std::string OnePart(const std::string& bytes, const std::string& type = "application/dicom") {
  return "--" + std::string(kBoundary) + "\r\nContent-Type: " + type + "\r\n\r\n" + bytes + "\r\n--" + kBoundary +
         "--\r\n";
}

// QIDO's listing of `count` instances, SOP Instance UIDs 4.5.6.1 and on.
std::string InstanceListing(int count) {
  std::string json = "[";
  for (int i = 1; i <= count; ++i) {
    json +=
        (i > 1 ? "," : "") + std::string(R"({"00080018":{"vr":"UI","Value":["4.5.6.)") + std::to_string(i) + R"("]}})";
  }
  return json + "]";
}

// A PACS of one series (1.2.3 / 4.5.6) of `count` instances, each answered by `instance(i)`.
LoopbackHttpServer::Handler SeriesPacs(int count, std::function<HttpAnswer(int)> instance) {
  return [count, instance](const HttpRequestSeen& request) {
    const std::string listing = kSeriesPath;
    if (StartsWith(request.target, listing + "?")) {
      return Answer(200, "application/dicom+json", InstanceListing(count));
    }
    if (StartsWith(request.target, listing + "/4.5.6.")) {
      return instance(std::stoi(request.target.substr(listing.size() + 7)));
    }
    return Answer(404, "text/plain", "not here");
  };
}

PacsConfig ConfigFor(const LoopbackHttpServer& server) {
  PacsConfig config = ParsePacsSpec("hostile=" + server.url() + "/dicom-web");
  config.connect_timeout = std::chrono::seconds(2);
  config.request_timeout = std::chrono::seconds(20);
  return config;
}

RetrieveStats RetrieveAll(const PacsConfig& config, std::atomic<int>* delivered = nullptr,
                          const std::atomic<bool>* cancel = nullptr) {
  RetrieveCallbacks callbacks;
  callbacks.on_instance = [delivered](const InstanceSummary&, const std::filesystem::path&, std::uint64_t) {
    if (delivered != nullptr) ++*delivered;
  };
  const cinevol::testing::ScratchDir folder;
  return DicomWebClient(config).RetrieveSeries(kStudy, kSeries, folder.path(), callbacks, cancel);
}

TEST(PacsHostileServer, RedirectIsNotFollowed) {
  LoopbackHttpServer elsewhere([](const HttpRequestSeen&) { return Answer(200, "application/dicom+json", "[]"); });
  LoopbackHttpServer pacs([&](const HttpRequestSeen&) {
    return Answer(302, "text/plain", "", "Location: " + elsewhere.url() + "/dicom-web/studies\r\n");
  });
  try {
    DicomWebClient(ConfigFor(pacs)).SearchStudies({});
    ADD_FAILURE() << "a redirect was followed";
  } catch (const PacsError& e) {
    EXPECT_EQ(e.http_status(), 302);
    EXPECT_NE(std::string(e.what()).find("HTTP 302, a redirect"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'hostile'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(pacs.connections(), 1);
  EXPECT_EQ(elsewhere.connections(), 0);
}

TEST(PacsHostileServer, MalformedInstanceAnswersAreClearErrors) {
  const std::string dicom = FakeInstance(1);
  const std::string dash = "--" + std::string(kBoundary);
  const std::string truncated = dash + "\r\nContent-Type: application/dicom\r\n\r\n" + dicom;
  const std::string two_parts = dash + "\r\n\r\n" + dicom + "\r\n" + dash + "\r\n\r\n" + dicom + "\r\n" + dash + "--";
  HttpAnswer no_boundary = InstanceAnswer(OnePart(dicom));
  no_boundary.head =
      "HTTP/1.1 200 OK\r\nContent-Type: multipart/related; type=\"application/dicom\"\r\n"
      "Connection: close\r\n\r\n";
  const std::vector<std::pair<HttpAnswer, std::string>> cases{
      {InstanceAnswer(truncated), "truncated"},
      {InstanceAnswer(two_parts), "more than 1 parts"},
      {InstanceAnswer(OnePart("<html>login</html>", "text/html")), "not application/dicom"},
      {InstanceAnswer(OnePart("not a DICOM file at all")), "not a DICOM Part 10 file"},
      {InstanceAnswer(dash + "--\r\n"), "no part"},
      {InstanceAnswer("garbage without any boundary"), "does not hold its boundary"},
      {no_boundary, "no boundary"},
      {Answer(200, "application/dicom", dicom), "not multipart/related"},
  };
  for (const auto& [answer, expected] : cases) {
    LoopbackHttpServer pacs(SeriesPacs(1, [&answer = answer](int) { return answer; }));
    const std::string error = ErrorOf<PacsError>([&] { RetrieveAll(ConfigFor(pacs)); });
    EXPECT_NE(error.find("malformed body"), std::string::npos) << error;
    EXPECT_NE(error.find(expected), std::string::npos) << "expected '" << expected << "' in: " << error;
  }
}

TEST(PacsHostileServer, BodyPastTheCapIsAbortedWhileArriving) {
  // No Content-Length: the cap can only be enforced as the bytes come.
  LoopbackHttpServer pacs([](const HttpRequestSeen&) {
    return HttpAnswer{"HTTP/1.1 200 OK\r\nContent-Type: application/dicom+json\r\nConnection: close\r\n\r\n", "[",
                      std::size_t{512} << 20};
  });
  PacsConfig config = ConfigFor(pacs);
  config.max_json_bytes = 1 << 20;
  const auto start = Clock::now();
  try {
    DicomWebClient(config).SearchStudies({});
    ADD_FAILURE() << "512 MiB accepted under a 1 MiB cap";
  } catch (const OverLimit& e) {
    EXPECT_EQ(e.flag(), "pacs-max-json-bytes");
    EXPECT_NE(std::string(e.what()).find("larger than the limit of 1048576 bytes (max_json_bytes)"), std::string::npos)
        << e.what();
  }
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(5));
  EXPECT_LT(pacs.bytes_sent(), std::size_t{64} << 20) << "the transfer was not aborted";
}

TEST(PacsHostileServer, AnnouncedBodyPastTheCapIsRefusedBeforeItArrives) {
  LoopbackHttpServer pacs(SeriesPacs(1, [](int) {
    HttpAnswer answer = InstanceAnswer("");
    answer.head = MultipartHead(std::size_t{1} << 30);  // announces 1 GiB
    answer.filler_bytes = std::size_t{1} << 30;
    return answer;
  }));
  PacsConfig config = ConfigFor(pacs);
  config.max_response_bytes = 1 << 20;
  const std::string error = ErrorOf<OverLimit>([&] { RetrieveAll(config); });
  EXPECT_NE(error.find("max_response_bytes"), std::string::npos) << error;
  EXPECT_LT(pacs.bytes_sent(), std::size_t{64} << 20);
}

TEST(PacsHostileServer, FetchesAtOnceNeverExceedParallelFetches) {
  constexpr int kInstances = 12;
  LoopbackHttpServer pacs(SeriesPacs(kInstances, [](int i) {
    HttpAnswer answer = InstanceAnswer(OnePart(FakeInstance(i)));
    answer.delay = std::chrono::milliseconds(150);  // long enough for the fetches to overlap
    return answer;
  }));
  PacsConfig config = ConfigFor(pacs);
  config.parallel_fetches = 3;
  std::atomic<int> delivered{0};
  const RetrieveStats stats = RetrieveAll(config, &delivered);
  EXPECT_EQ(delivered.load(), kInstances);
  EXPECT_EQ(pacs.most_at_once(), 3) << "as the PACS saw it";
  EXPECT_EQ(stats.most_fetches_at_once, 3) << "as the client counted";
  EXPECT_EQ(pacs.connections(), 1 + kInstances);
}

TEST(PacsHostileServer, CancelStopsAHangingRetrieveWithinAboutASecond) {
  LoopbackHttpServer pacs(SeriesPacs(4, [](int i) {
    HttpAnswer answer = InstanceAnswer(OnePart(FakeInstance(i)));
    answer.delay = std::chrono::seconds(30);  // cut short when the server stops
    return answer;
  }));
  std::atomic<bool> cancel{false};
  Clock::time_point cancelled_at;
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    cancelled_at = Clock::now();
    cancel = true;
  });
  std::atomic<int> delivered{0};
  EXPECT_THROW(RetrieveAll(ConfigFor(pacs), &delivered, &cancel), Cancelled);
  const auto stopped_at = Clock::now();
  canceller.join();
  EXPECT_LT(stopped_at - cancelled_at, std::chrono::milliseconds(1500));
  EXPECT_EQ(delivered.load(), 0);
}

TEST(PacsHostileServer, SlowPacsTimesOutWithAClearError) {
  LoopbackHttpServer pacs([](const HttpRequestSeen&) {
    HttpAnswer answer = Answer(200, "application/dicom+json", "[]");
    answer.delay = std::chrono::seconds(30);
    return answer;
  });
  PacsConfig config = ConfigFor(pacs);
  config.request_timeout = std::chrono::milliseconds(500);
  const auto start = Clock::now();
  const std::string error = ErrorOf<PacsError>([&] { DicomWebClient(config).SearchStudies({}); });
  EXPECT_NE(error.find("did not answer a search for studies in time"), std::string::npos) << error;
  EXPECT_NE(error.find("request_timeout 500 ms"), std::string::npos) << error;
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(3));
}

TEST(PacsHostileServer, DownPacsAndErrorStatusesNameThePacs) {
  PacsConfig down;
  {
    LoopbackHttpServer closed([](const HttpRequestSeen&) { return Answer(200, "text/plain", ""); });
    down = ConfigFor(closed);
  }  // nothing listens on its port now
  std::string error = ErrorOf<PacsError>([&] { DicomWebClient(down).SearchStudies({}); });
  EXPECT_NE(error.find("PACS 'hostile' could not be reached for a search for studies"), std::string::npos) << error;
  LoopbackHttpServer failing([](const HttpRequestSeen&) { return Answer(500, "text/html", "<h1>oops</h1>"); });
  error = ErrorOf<PacsError>([&] { DicomWebClient(ConfigFor(failing)).SearchSeries(kStudy); });
  EXPECT_NE(error.find("PACS 'hostile' answered a search for a study's series with HTTP 500"), std::string::npos)
      << error;
  LoopbackHttpServer not_json([](const HttpRequestSeen&) { return Answer(200, "text/html", "<h1>portal</h1>"); });
  error = ErrorOf<PacsError>([&] { DicomWebClient(ConfigFor(not_json)).SearchStudies({}); });
  EXPECT_NE(error.find("not DICOM JSON"), std::string::npos) << error;
}

TEST(PacsHostileServer, BadUidsAndQueriesAreRefusedBeforeAnyRequest) {
  LoopbackHttpServer pacs([](const HttpRequestSeen&) { return Answer(200, "application/dicom+json", "[]"); });
  const DicomWebClient client(ConfigFor(pacs));
  const std::string dicom = FakeInstance(0);
  for (const std::string& bad :
       std::vector<std::string>{"", "1.2/../../system", "1.2?x=1", "1..2", "1.2%2F", "http://elsewhere/",
                                std::string(65, '1'), std::string("1.2\0.3", 6)}) {
    EXPECT_THROW(client.RetrieveSeries(kStudy, bad, "/nonexistent", {}), InputError) << bad;
    EXPECT_THROW(client.RetrieveSeries(bad, kSeries, "/nonexistent", {}), InputError) << bad;
    EXPECT_THROW(client.SearchSeries(bad), InputError) << bad;
    EXPECT_THROW(client.StoreInstances(bad, {dicom}), InputError) << bad;
  }
  StudyQuery query;
  query.patient_id = "A\\B";
  EXPECT_THROW(client.SearchStudies(query), InputError);
  query = {};
  query.study_date_from = "2022-01-01";
  EXPECT_THROW(client.SearchStudies(query), InputError);
  query = {};
  query.modality = "CT&x=1";
  EXPECT_THROW(client.SearchStudies(query), InputError);
  query = {};
  query.patient_name = std::string(65, 'A');
  EXPECT_THROW(client.SearchStudies(query), InputError);
  EXPECT_THROW(client.StoreInstances(kStudy, {"not a DICOM file"}), InputError);
  EXPECT_EQ(pacs.connections(), 0);
}

TEST(PacsHostileServer, SearchValuesAreEscapedIntoTheQuery) {
  LoopbackHttpServer pacs([](const HttpRequestSeen&) { return Answer(200, "application/dicom+json", "[]"); });
  StudyQuery query;
  query.patient_name = "O'Brien&limit=99999 #x+%";
  query.limit = 7;
  DicomWebClient(ConfigFor(pacs)).SearchStudies(query);
  query.patient_name = "DOE^J?HN*";  // DICOM's matching characters go as they are (docs/pacs.md)
  query.patient_id = "Zo\u00eb";
  DicomWebClient(ConfigFor(pacs)).SearchStudies(query);
  ASSERT_EQ(pacs.requests().size(), 2u);
  std::string target = pacs.requests()[0].target;
  EXPECT_TRUE(StartsWith(target, "/dicom-web/studies?PatientName=O%27Brien%26limit%3D99999%20%23x%2B%25&limit=7&"))
      << target;
  target = pacs.requests()[1].target;
  EXPECT_TRUE(StartsWith(target, "/dicom-web/studies?PatientName=DOE^J?HN*&PatientID=Zo%C3%AB&limit=7&")) << target;
}

TEST(PacsHostileServer, ListingPastMaxInstancesIsRefusedBeforeAnyFetch) {
  LoopbackHttpServer pacs(SeriesPacs(10, [](int i) { return InstanceAnswer(OnePart(FakeInstance(i))); }));
  PacsConfig config = ConfigFor(pacs);
  config.max_instances = 5;
  const std::string error = ErrorOf<OverLimit>([&] { RetrieveAll(config); });
  EXPECT_NE(error.find("more than 5 instances, the limit (max_instances)"), std::string::npos) << error;
  ASSERT_EQ(pacs.requests().size(), 1u);
  EXPECT_NE(pacs.requests()[0].target.find("limit=6"), std::string::npos) << pacs.requests()[0].target;
}

TEST(PacsHostileServer, HostileSearchAnswersAreReadSafely) {
  const std::string huge_name(1 << 20, 'N');
  LoopbackHttpServer pacs([&](const HttpRequestSeen&) {
    std::string json = "[";
    json += R"({"00100010":{"vr":"PN","Value":[{"Alphabetic":")" + huge_name + R"("}]}},)";  // no study UID
    json += R"({"0020000D":{"vr":"UI","Value":["1.2/../x"]}},)";                             // not a UID
    for (int i = 1; i <= 5; ++i) {
      json += R"({"0020000D":{"vr":"UI","Value":["9.)" + std::to_string(i) +
              R"("]},"00100010":{"vr":"PN","Value":[{"Alphabetic":")" + huge_name + R"("}]},)" +
              R"("00201206":{"vr":"IS","Value":["many"]}})" + (i < 5 ? "," : "");
    }
    return Answer(200, "application/dicom+json", json + "]");
  });
  PacsConfig config = ConfigFor(pacs);
  config.max_json_bytes = 16 << 20;
  StudyQuery query;
  query.limit = 3;  // a PACS that ignores the limit is cut off at it
  const auto studies = DicomWebClient(config).SearchStudies(query);
  ASSERT_EQ(studies.size(), 3u);
  EXPECT_EQ(studies[0].study_uid, "9.1");
  EXPECT_EQ(studies[0].patient_name.size(), kMaxDicomText);
  EXPECT_FALSE(studies[0].series_count.has_value());
}

TEST(PacsHostileServer, CredentialsTravelAsHeadersNeverInTheUrl) {
  LoopbackHttpServer pacs([](const HttpRequestSeen&) { return Answer(200, "application/dicom+json", "[]"); });
  PacsConfig config = ConfigFor(pacs);
  config.credentials.kind = PacsCredentials::Kind::kBearer;
  config.credentials.token = "tok-3f9a";
  DicomWebClient(config).SearchStudies({});
  config.credentials = {PacsCredentials::Kind::kBasic, "reader", "pw-77", ""};
  DicomWebClient(config).SearchStudies({});
  const auto requests = pacs.requests();
  ASSERT_EQ(requests.size(), 2u);
  EXPECT_NE(requests[0].head.find("Authorization: Bearer tok-3f9a\r\n"), std::string::npos) << requests[0].head;
  EXPECT_NE(requests[1].head.find("Authorization: Basic cmVhZGVyOnB3LTc3\r\n"), std::string::npos)  // reader:pw-77
      << requests[1].head;
  for (const auto& request : requests) EXPECT_EQ(request.target.find("pw-77"), std::string::npos);
}

TEST(PacsHostileServer, StoreReportsThePacssFailures) {
  const std::string answer = R"({"00081198":{"vr":"SQ","Value":[{"00081155":{"vr":"UI","Value":["7.7.1"]},)"
                             R"("00081197":{"vr":"US","Value":[42752]}}]},"00081199":{"vr":"SQ","Value":[)"
                             R"({"00081155":{"vr":"UI","Value":["7.7.2"]}}]}})";
  LoopbackHttpServer pacs([&](const HttpRequestSeen&) { return Answer(202, "application/dicom+json", answer); });
  const std::string error = ErrorOf<PacsError>([&] {
    DicomWebClient(ConfigFor(pacs)).StoreInstances(kStudy, {FakeInstance(1), FakeInstance(2)});
  });
  EXPECT_NE(error.find("stored 1 of 2 instances (HTTP 202); refused: 7.7.1: 0xa700 (out of resources)"),
            std::string::npos)
      << error;
  ASSERT_EQ(pacs.requests().size(), 1u);
  EXPECT_EQ(pacs.requests()[0].method, "POST");
  EXPECT_EQ(pacs.requests()[0].target, "/dicom-web/studies/1.2.3");
  EXPECT_NE(pacs.requests()[0].head.find("Content-Type: multipart/related; type=\"application/dicom\"; boundary="),
            std::string::npos);
}

}  // namespace
}  // namespace cinevol::pacs

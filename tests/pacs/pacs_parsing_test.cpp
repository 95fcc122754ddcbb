// What server/pacs reads from the operator and from a PACS without a network:
// `--pacs NAME=URL`, the credentials file, multipart bodies, DICOM JSON, UIDs.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <string>

#include "core/error.h"
#include "pacs/dicom_json.h"
#include "pacs/frame_plane.h"
#include "pacs/multipart.h"
#include "pacs/pacs_config.h"
#include "pacs/pacs_error.h"
#include "support/error_of.h"

namespace cinevol::pacs {
namespace {

std::string SpecError(const std::string& spec) {
  try {
    ParsePacsSpec(spec);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

std::string CredentialsError(const std::string& text) {
  try {
    ParseCredentials(text, "pacs-credentials");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(accepted)";
}

std::string SplitError(std::string_view body, std::size_t max_parts = 4) {
  try {
    SplitMultipart(body, "b0undary", max_parts);
  } catch (const MultipartError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(PacsConfig, ParsesNameEqualsUrlWithTheDefaults) {
  const PacsConfig config = ParsePacsSpec("main_pacs-1=HTTPS://pacs.example.org:8443/dicom-web/");
  EXPECT_EQ(config.name, "main_pacs-1");
  EXPECT_EQ(config.base_url, "https://pacs.example.org:8443/dicom-web");
  EXPECT_EQ(config.parallel_fetches, 4);
  EXPECT_EQ(config.credentials.kind, PacsCredentials::Kind::kNone);
  EXPECT_NO_THROW(ValidatePacsConfig(config));
}

TEST(PacsConfig, RefusesEverySchemeButHttpAndHttps) {
  for (const char* url : {"ftp://pacs/dicom-web", "file:///etc/passwd", "gopher://pacs:70/", "dict://pacs:11211/",
                          "ldap://pacs/", "javascript:alert(1)", "pacs.example.org/dicom-web", "//pacs/dicom-web"}) {
    const std::string error = SpecError(std::string("p=") + url);
    EXPECT_NE(error, "(accepted)") << url;
    EXPECT_NE(error.find("PACS URL"), std::string::npos) << error;
  }
}

TEST(PacsConfig, RefusesUserInfoQueriesFragmentsAndSpaces) {
  EXPECT_NE(SpecError("p=http://user:secret@pacs/dicom-web").find("credentials file"), std::string::npos);
  EXPECT_EQ(SpecError("p=http://user:secret@pacs/dicom-web").find("secret"), std::string::npos);
  EXPECT_NE(SpecError("p=http://pacs/dicom-web?x=1").find("query"), std::string::npos);
  EXPECT_NE(SpecError("p=http://pacs/dicom-web#top").find("fragment"), std::string::npos);
  EXPECT_NE(SpecError("p=http://pacs/dicom web").find("spaces"), std::string::npos);
  EXPECT_NE(SpecError("p=http://pacs\\dicom-web").find("backslashes"), std::string::npos);
}

TEST(PacsConfig, RefusesNamesOutsideTheirAlphabet) {
  for (const char* spec :
       {"=http://pacs", "a b=http://pacs", "a/b=http://pacs", "a.b=http://pacs", "ünï=http://pacs", "no-url"}) {
    EXPECT_NE(SpecError(spec), "(accepted)") << spec;
  }
  EXPECT_FALSE(IsValidPacsName(std::string(65, 'a')));
  EXPECT_TRUE(IsValidPacsName(std::string(64, 'a')));
}

TEST(PacsConfig, ValidationNamesTheFieldOutOfRange) {
  PacsConfig config = ParsePacsSpec("p=http://127.0.0.1:1/dicom-web");
  config.parallel_fetches = 0;
  try {
    ValidatePacsConfig(config);
    ADD_FAILURE() << "parallel_fetches 0 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parallel_fetches"), std::string::npos) << e.what();
  }
  config.parallel_fetches = 4;
  config.base_url = "http://127.0.0.1:1/dicom-web/";  // not normalised
  EXPECT_THROW(ValidatePacsConfig(config), InputError);
}

TEST(PacsCredentials, ReadsBasicAndBearerLinesAndComments) {
  const auto credentials = ParseCredentials(
      "# the hospital's PACS\n\n  main basic reader:pa:ss#word  \nvna bearer eyJ0b2tlbi4uLg\n", "file");
  ASSERT_EQ(credentials.size(), 2u);
  EXPECT_EQ(credentials.at("main").kind, PacsCredentials::Kind::kBasic);
  EXPECT_EQ(credentials.at("main").user, "reader");
  EXPECT_EQ(credentials.at("main").password, "pa:ss#word");  // only the first colon splits
  EXPECT_EQ(credentials.at("vna").kind, PacsCredentials::Kind::kBearer);
  EXPECT_EQ(credentials.at("vna").token, "eyJ0b2tlbi4uLg");
}

TEST(PacsCredentials, ErrorsNameTheLineButNeverItsSecrets) {
  const std::string secret = "hunter2-secret";
  for (const std::string& text :
       {"main basic " + secret, "main basic :" + secret, "main digest user:" + secret, "main bearer " + secret + " x",
        secret + "/x basic user:pw", "main basic user:" + secret + "\nmain basic user:" + secret}) {
    const std::string error = CredentialsError("# comment\n" + text);
    EXPECT_NE(error, "(accepted)") << text;
    EXPECT_NE(error.find("pacs-credentials line"), std::string::npos) << error;
    EXPECT_EQ(error.find(secret), std::string::npos) << error;
    EXPECT_EQ(error.find("hunter"), std::string::npos) << error;
  }
}

TEST(PacsMultipart, FindsTheBoundaryQuotedOrNot) {
  EXPECT_EQ(MultipartBoundary("multipart/related; type=\"application/dicom\"; boundary=abc-123"), "abc-123");
  EXPECT_EQ(MultipartBoundary("Multipart/Related;boundary=\"a:b c\";type=\"application/dicom;x\""), "a:b c");
  EXPECT_THROW(MultipartBoundary("multipart/related; boundary=\"a;b\""), MultipartError);  // ; is no bchar
  EXPECT_THROW(MultipartBoundary("multipart/related; type=\"application/dicom\""), MultipartError);
  EXPECT_THROW(MultipartBoundary("application/dicom; boundary=abc"), MultipartError);
  EXPECT_THROW(MultipartBoundary("multipart/related; boundary="), MultipartError);
  EXPECT_THROW(MultipartBoundary("multipart/related; boundary=\"" + std::string(71, 'a') + "\""), MultipartError);
  EXPECT_THROW(MultipartBoundary("multipart/related; boundary=\"unterminated"), MultipartError);
}

TEST(PacsMultipart, SplitsPartsAndKeepsTheirBytesExactly) {
  const std::string binary("\0\r\n--b0undar\r\n\xff", 15);
  const std::string body = "preamble\r\n--b0undary\r\nContent-Type: application/dicom\r\n\r\n" + binary +
                           "\r\n--b0undary  \r\n\r\nsecond\r\n--b0undary--\r\nepilogue";
  const auto parts = SplitMultipart(body, "b0undary", 4);
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0].body, binary);
  EXPECT_EQ(PartMediaType(parts[0].headers), "application/dicom");
  EXPECT_EQ(parts[1].body, "second");
  EXPECT_EQ(PartMediaType(parts[1].headers), "");
}

TEST(PacsMultipart, RefusesTruncatedAndMalformedBodies) {
  const std::string part = "--b0undary\r\nContent-Type: application/dicom\r\n\r\nDATA";
  EXPECT_NE(SplitError(part).find("truncated"), std::string::npos);
  EXPECT_NE(SplitError(part + "\r\n--b0undary").find("truncated"), std::string::npos);
  EXPECT_NE(SplitError("--b0undary\r\nContent-Type: x").find("blank line"), std::string::npos);
  EXPECT_NE(SplitError("no boundary anywhere").find("does not hold its boundary"), std::string::npos);
  EXPECT_NE(SplitError("--b0undaryX\r\n\r\nx\r\n--b0undary--").find("CRLF"), std::string::npos);
  EXPECT_NE(SplitError("").find("does not hold its boundary"), std::string::npos);
  const std::string three = "--b0undary\r\n\r\n1\r\n--b0undary\r\n\r\n2\r\n--b0undary\r\n\r\n3\r\n--b0undary--";
  EXPECT_NE(SplitError(three, 2).find("more than 2 parts"), std::string::npos);
}

TEST(PacsMultipart, WhatIsJoinedSplitsBackIntoTheSameParts) {
  const std::vector<std::string> parts{std::string(300, '\0') + "DICM", "second\r\n--almost"};
  const std::string boundary = NewBoundary();
  EXPECT_EQ(boundary.size(), 48u);
  const auto split = SplitMultipart(JoinMultipart(parts, boundary, "application/dicom"), boundary, 8);
  ASSERT_EQ(split.size(), 2u);
  EXPECT_EQ(split[0].body, parts[0]);
  EXPECT_EQ(split[1].body, parts[1]);
  EXPECT_NE(NewBoundary(), boundary);
}

TEST(PacsDicomJson, UidsAreDigitsAndDotsAtMost64) {
  EXPECT_TRUE(IsValidUid("1.2.840.10008.5.1.4.1.1.2"));
  EXPECT_TRUE(IsValidUid("2.25." + std::string(59, '9')));
  EXPECT_FALSE(IsValidUid("2.25." + std::string(60, '9')));
  for (const char* bad : {"", ".1.2", "1.2.", "1..2", "1.2/../3", "1.2?x=1", "1.2%2F3", "1.2 3", "abc", "1.2\n3"}) {
    EXPECT_FALSE(IsValidUid(bad)) << bad;
  }
}

TEST(PacsDicomJson, HostileValuesReadAsAbsent) {
  const std::string json = R"([
    {"0020000D": {"vr": "UI", "Value": ["1.2.3"]},
     "00100010": {"vr": "PN", "Value": [{"Alphabetic": ")" +
                           std::string(100000, 'A') + R"("}]},
     "00100020": {"vr": "LO", "Value": [{"nested": ["object"]}]},
     "00201206": {"vr": "IS", "Value": [-4]},
     "00201208": {"vr": "IS", "Value": [" 17 "]},
     "00201209": {"vr": "IS", "Value": [1e300]},
     "00080061": {"vr": "CS", "Value": "not an array"},
     "00080020": "not an object"},
    "not a data set", 42,
    {"0020000e": {"vr": "UI", "Value": ["4.5.6"]}}
  ])";
  JsonDocument storage;
  const auto datasets = ParseDicomJson(json, storage);
  ASSERT_EQ(datasets.size(), 2u);
  EXPECT_EQ(datasets[0].Text(0x0020000D), "1.2.3");
  EXPECT_EQ(datasets[0].PersonName(0x00100010).size(), kMaxDicomText);
  EXPECT_EQ(datasets[0].Text(0x00100020), "");
  EXPECT_FALSE(datasets[0].Count(0x00201206).has_value());
  EXPECT_EQ(datasets[0].Count(0x00201208), 17);
  EXPECT_FALSE(datasets[0].Count(0x00201209).has_value());
  EXPECT_TRUE(datasets[0].Texts(0x00080061, 16).empty());
  EXPECT_EQ(datasets[0].Text(0x00080020), "");
  EXPECT_EQ(datasets[1].Text(0x0020000E), "4.5.6");  // lower-case tags read too
}

TEST(PacsDicomJson, DeepNestingAndGarbageAreErrorsNotHangsOrCrashes) {
  JsonDocument storage;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(ParseDicomJson(std::string(1000000, '[') + std::string(1000000, ']'), storage), std::invalid_argument);
  EXPECT_THROW(ParseDicomJson("[\"\\\"[[\"" + std::string(33, '{'), storage), std::invalid_argument);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  const std::string sequences_10_deep = [] {
    std::string json = "[";
    for (int i = 0; i < 10; ++i) json += R"({"00081199":{"vr":"SQ","Value":[)";
    json += "{}";
    for (int i = 0; i < 10; ++i) json += "]}}";
    return json + "]";
  }();
  EXPECT_EQ(ParseDicomJson(sequences_10_deep, storage).size(), 1u);
  EXPECT_THROW(ParseDicomJson("{\"unterminated", storage), std::invalid_argument);
  EXPECT_THROW(ParseDicomJson("\"a string\"", storage), std::invalid_argument);
  EXPECT_TRUE(ParseDicomJson("[]", storage).empty());
  EXPECT_TRUE(ParseDicomJson("null", storage).empty());
}

// The attack that passed the old depth check: a single-quoted string (which a
// lenient parser takes) holding a double quote hid 100,000 levels from it.
TEST(PacsDicomJson, OnlyStrictJsonIsRead) {
  JsonDocument storage;
  const std::string hidden = "['\"', " + std::string(100000, '[') + std::string(100000, ']') + "]";
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(ParseDicomJson(hidden, storage), JsonError);
  for (const char* lenient : {"['a']", "[1,]", "{\"a\":1,}", "[NaN]", "[Infinity]", "[01]", "[1.]", "[.5]", "[+1]",
                              "// comment\n[]", "[\"tab\there\"]", "[\"\\x41\"]", "{a:1}", "[] []", "[\"\\u12\"]"}) {
    EXPECT_THROW(ParseDicomJson(lenient, storage), JsonError) << lenient;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  const JsonDocument doc =
      JsonDocument::Parse(R"({"s":"\u00e9\ud83d\ude00\ud800x\"\/","n":-1.5e3,"big":1e999,"t":true})");
  EXPECT_EQ(doc.root().member("s").text(), "\u00e9\U0001F600\uFFFDx\"/");
  EXPECT_EQ(doc.root().member("n").number(), -1500);
  EXPECT_TRUE(std::isinf(doc.root().member("big").number()));
  EXPECT_TRUE(doc.root().member("t").is(JsonDocument::Kind::kTrue));
  EXPECT_FALSE(doc.root().member("absent").valid());
}

// Memory is bounded by the count of values, known before it is taken; a
// raised flag stops the parse.
TEST(PacsDicomJson, ValuesAreCountedAndTheParseCanBeCancelled) {
  std::string many = "[";
  for (int i = 0; i < 2000; ++i) many += "[],";
  many += "0]";
  const std::string error =
      cinevol::testing::ErrorOf<JsonError>([&] { JsonDocument::Parse(many, {.max_values = 1000}); });
  EXPECT_NE(error.find("more than 1000 values"), std::string::npos) << error;
  EXPECT_NO_THROW(JsonDocument::Parse(many, {.max_values = 5000}));
  const std::atomic<bool> cancel{true};
  EXPECT_THROW(JsonDocument::Parse(std::string(1 << 20, ' ') + "[]", {}, &cancel), Cancelled);
}

// A text cut to kMaxDicomText never splits a character, and malformed UTF-8
// becomes U+FFFD: a client that checks UTF-8 takes every answer.
TEST(PacsDicomJson, TextsAreValidUtf8CutBetweenCharacters) {
  const std::string e_acute = "\xC3\xA9";  // two bytes
  std::string name;
  for (int i = 0; i < 200; ++i) name += e_acute;
  const std::string cut = CleanText(name);
  EXPECT_EQ(cut.size(), kMaxDicomText);
  EXPECT_EQ(CleanText("a" + name).size(), kMaxDicomText - 1);  // 255 bytes: the 128th character does not fit
  EXPECT_EQ(CleanText("ok\xFF\xC3(\xED\xA0\x80\xF4\x90\x80\x80z"),
            "ok\uFFFD\uFFFD(\uFFFD\uFFFD\uFFFD\uFFFD\uFFFD\uFFFD\uFFFDz");
  JsonDocument storage;
  const auto datasets =
      ParseDicomJson("[{\"00100010\":{\"vr\":\"PN\",\"Value\":[{\"Alphabetic\":\"a" + name + "\"}]}}]", storage);
  ASSERT_EQ(datasets.size(), 1u);
  EXPECT_EQ(datasets[0].PersonName(0x00100010), CleanText("a" + name));
}

// An instance's metadata as WADO-RS answers it, `attributes` inside its one data set.
FramePlane PlaneIn(const std::string& attributes, int frame) {
  JsonDocument storage;
  const auto datasets = ParseDicomJson("[{" + attributes + "}]", storage);
  return FramePlaneOf(datasets.at(0), frame);
}

constexpr const char* kMatrix = R"("00280010":{"vr":"US","Value":[4]},"00280011":{"vr":"US","Value":[6]})";
constexpr const char* kAxial =
    R"("00200032":{"vr":"DS","Value":[-10.5,"20",30.25]},"00200037":{"vr":"DS","Value":[1,0,0,0,1,0]},)"
    R"("00280030":{"vr":"DS","Value":["0.5 ",0.75]})";

// A single-frame image is placed by its top-level attributes, DS values as
// numbers or as strings.
TEST(PacsFramePlane, ASingleFrameImageIsPlacedByItsOwnAttributes) {
  const FramePlane plane = PlaneIn(std::string(kMatrix) + "," + kAxial, 0);
  EXPECT_EQ(plane.position, (Triple{-10.5, 20, 30.25}));
  EXPECT_EQ(plane.row, (Triple{1, 0, 0}));
  EXPECT_EQ(plane.column, (Triple{0, 1, 0}));
  EXPECT_EQ(plane.rows, 4);
  EXPECT_EQ(plane.columns, 6);
  EXPECT_EQ(plane.row_spacing_mm, 0.5);
  EXPECT_EQ(plane.column_spacing_mm, 0.75);
  EXPECT_EQ(PlaneIn(std::string(kMatrix) + "," + kAxial, 1).position, plane.position);
  EXPECT_NE(cinevol::testing::ErrorOf<PacsError>([&] {
              PlaneIn(std::string(kMatrix) + "," + kAxial, 2);
            }).find("the instance has 1 frame; frame 2 is not one of them"),
            std::string::npos);
}

// An enhanced multi-frame image: each frame's position in its own functional
// group, orientation and spacing shared; frame 0 names none of several.
TEST(PacsFramePlane, AnEnhancedImagesFramesArePlacedByTheirFunctionalGroups) {
  const std::string frame_group = R"({"00209113":{"vr":"SQ","Value":[{"00200032":{"vr":"DS","Value":[0,0,%]}}]}})";
  std::string per_frame;
  for (int z : {5, 7, 9}) {
    std::string group = frame_group;
    group.replace(group.find('%'), 1, std::to_string(z));
    per_frame += (per_frame.empty() ? "" : ",") + group;
  }
  const std::string enhanced =
      std::string(kMatrix) + R"(,"00280008":{"vr":"IS","Value":["3"]},)" +
      R"("52009229":{"vr":"SQ","Value":[{"00209116":{"vr":"SQ","Value":[{"00200037":{"vr":"DS","Value":[0,1,0,0,0,-1]}}]},)"
      R"("00289110":{"vr":"SQ","Value":[{"00280030":{"vr":"DS","Value":[2,3]}}]}}]},)"
      R"("52009230":{"vr":"SQ","Value":[)" +
      per_frame + "]}";
  const FramePlane second = PlaneIn(enhanced, 2);
  EXPECT_EQ(second.position, (Triple{0, 0, 7}));
  EXPECT_EQ(second.row, (Triple{0, 1, 0}));
  EXPECT_EQ(second.column, (Triple{0, 0, -1}));
  EXPECT_EQ(second.row_spacing_mm, 2);
  EXPECT_EQ(PlaneIn(enhanced, 3).position, (Triple{0, 0, 9}));
  EXPECT_NE(cinevol::testing::ErrorOf<InputError>([&] {
              PlaneIn(enhanced, 0);
            }).find("the instance has 3 frames: ask for one"),
            std::string::npos);
  EXPECT_NE(cinevol::testing::ErrorOf<PacsError>([&] { PlaneIn(enhanced, 4); }).find("frame 4 is not one"),
            std::string::npos);
}

// Metadata that does not place a frame is an error naming what is wrong, never a slice of somewhere.
TEST(PacsFramePlane, MetadataThatDoesNotPlaceAFrameIsRefusedByName) {
  const std::string matrix = kMatrix;
  const auto error = [](const std::string& attributes) {
    return cinevol::testing::ErrorOf<InputError>([&] { PlaneIn(attributes, 1); });
  };
  EXPECT_NE(error(matrix).find("Image Position (Patient) missing"), std::string::npos);
  const std::string no_spacing =
      R"("00200032":{"vr":"DS","Value":[0,0,0]},"00200037":{"vr":"DS","Value":[1,0,0,0,1,0]})";
  EXPECT_NE(error(matrix + "," + no_spacing).find("Pixel Spacing missing"), std::string::npos);
  const std::string far = R"("00200032":{"vr":"DS","Value":[0,0,1e12]},"00200037":{"vr":"DS","Value":[1,0,0,0,1,0]},)"
                          R"("00280030":{"vr":"DS","Value":[1,1]})";
  EXPECT_NE(error(matrix + "," + far).find("not within 1e+09 mm"), std::string::npos);
  const std::string parallel = R"("00200032":{"vr":"DS","Value":[0,0,0]},"00200037":{"vr":"DS","Value":[1,0,0,1,0,0]},)"
                               R"("00280030":{"vr":"DS","Value":[1,1]})";
  EXPECT_NE(error(matrix + "," + parallel).find("not two perpendicular directions"), std::string::npos);
  const std::string tiny = R"("00200032":{"vr":"DS","Value":[0,0,0]},"00200037":{"vr":"DS","Value":[1,0,0,0,1,0]},)"
                           R"("00280030":{"vr":"DS","Value":[1e-10,1]})";
  EXPECT_NE(error(matrix + "," + tiny).find("outside [1e-4, 1e4]"), std::string::npos);
  const std::string nan = R"("00200032":{"vr":"DS","Value":["NaN",0,0]},"00200037":{"vr":"DS","Value":[1,0,0,0,1,0]},)"
                          R"("00280030":{"vr":"DS","Value":[1,1]})";
  EXPECT_NE(error(matrix + "," + nan).find("Image Position (Patient) missing"), std::string::npos);
  EXPECT_NE(error(std::string(kAxial)).find("Rows is missing"), std::string::npos);
}

}  // namespace
}  // namespace cinevol::pacs

// Session scripts' "slice" and "pick" lines (issue 36, docs/client.md): read
// into the requests they name, kept apart from the events, and refused with
// their line when they would write outside the run's folder or name a field
// the request does not have.
#include "session_script.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/error.h"

namespace cinevol::testing {
namespace {

// The message ParseScript throws for `text`, or "" when it parses.
std::string ParseError(const std::string& text) {
  try {
    cli::ParseScript(text, "reading.jsonl");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(SessionScript, SliceAndPickLinesBecomeTheirRequestsBesideTheEvents) {
  const cli::SessionScript script = cli::ParseScript(
      R"({"session": {"volume": "phantom:head?size=48"}}
{"at": 0.5, "camera": {"view": "LEFT"}}
{"at": 1, "slice": {"axis": "oblique", "point": {"x": 1, "y": 2, "z": 3}, "normal": {"z": 1}, "row": {"x": 1}, "windowPreset": "bone", "slabMm": 4, "projection": "mean", "out": "tilted.png"}}
{"at": 1, "pick": {"x": 48, "y": 32, "threshold": 0.25}}
{"at": 2, "slice": {"axis": "CORONAL", "positionMm": -3.5, "window": 400, "level": 40, "out": "coronal.png"}}
)",
      "reading.jsonl");
  ASSERT_EQ(script.steps.size(), 1u) << "events only: a player that knows no calls passes over them";
  ASSERT_EQ(script.calls.size(), 3u);

  const cli::ScriptStep& oblique = script.calls[0];
  EXPECT_EQ(oblique.line, 3);
  EXPECT_DOUBLE_EQ(oblique.at, 1);
  ASSERT_TRUE(oblique.call && oblique.call->slice);
  const v1::SliceRequest& s = *oblique.call->slice;
  EXPECT_EQ(oblique.call->out, "tilted.png");
  EXPECT_EQ(s.axis(), v1::OBLIQUE) << "an enum as the command line writes it";
  EXPECT_EQ(s.point().z(), 3);
  EXPECT_EQ(s.normal().z(), 1);
  EXPECT_EQ(s.window_preset(), "bone");
  EXPECT_FLOAT_EQ(s.slab_mm(), 4);
  EXPECT_EQ(s.projection(), v1::MEAN);
  EXPECT_TRUE(s.session_id().empty()) << "the player fills it in";

  const cli::ScriptStep& pick = script.calls[1];
  ASSERT_TRUE(pick.call && pick.call->pick && !pick.call->slice);
  EXPECT_FLOAT_EQ(pick.call->pick->x(), 48);
  EXPECT_FLOAT_EQ(pick.call->pick->threshold(), 0.25f);

  const v1::SliceRequest& coronal = *script.calls[2].call->slice;
  EXPECT_EQ(coronal.axis(), v1::CORONAL);
  EXPECT_DOUBLE_EQ(coronal.position_mm(), -3.5);
  EXPECT_TRUE(coronal.has_window() && coronal.has_level());

  // In a timeline: by time, then in the file's order.
  const std::vector<cli::ScriptStep> timeline = cli::WithCalls(script.steps, script.calls);
  ASSERT_EQ(timeline.size(), 4u);
  EXPECT_EQ(timeline[0].line, 2);
  EXPECT_EQ(timeline[1].line, 3);
  EXPECT_EQ(timeline[2].line, 4);
  EXPECT_EQ(timeline[3].line, 5);
}

TEST(SessionScript, ASliceThatWouldWriteOutsideItsFolderIsRefusedWithItsLine) {
  for (const char* out : {"../escape.png", "a/b.png", "/tmp/x.png", "slice.jpg", ".png", "a..png", "x\\\\y.png"}) {
    const std::string error = ParseError(std::string(R"({"at": 0, "camera": {"view": "LEFT"}}
{"at": 1, "slice": {"axis": "AXIAL", "out": ")") +
                                         out + R"("}}
)");
    EXPECT_TRUE(Has(error, "reading.jsonl line 2: slice.out")) << out << ": " << error;
    EXPECT_TRUE(Has(error, "ending in .png")) << error;
  }
  EXPECT_TRUE(Has(ParseError(R"({"at": 1, "slice": {"axis": "AXIAL"}})"), "line 1: slice.out: missing"));
  EXPECT_TRUE(Has(ParseError(R"({"at": 1, "slice": {"out": 7}})"), "line 1: slice.out: must be a string"));
  const std::string twice = ParseError(R"({"at": 1, "slice": {"out": "a.png"}}
{"at": 2, "slice": {"axis": "SAGITTAL", "out": "a.png"}}
)");
  EXPECT_TRUE(Has(twice, "line 2: slice.out: a.png is written by line 1 already")) << twice;
}

TEST(SessionScript, UnknownOrPlayerOwnedFieldsOfACallAreRefused) {
  const std::string slice = ParseError(R"({"at": 0, "slice": {"axis": "AXIAL", "positon": 3, "out": "a.png"}})");
  EXPECT_TRUE(Has(slice, "reading.jsonl line 1: slice")) << slice;
  EXPECT_TRUE(Has(slice, "positon")) << slice;
  const std::string pick = ParseError(R"({"at": 0, "pick": {"x": 3, "y": 4, "treshold": 0.5}})");
  EXPECT_TRUE(Has(pick, "reading.jsonl line 1: pick")) << pick;
  EXPECT_TRUE(Has(pick, "treshold")) << pick;
  EXPECT_TRUE(Has(ParseError(R"({"at": 0, "slice": {"axis": "SIDEWAYS", "out": "a.png"}})"), "line 1: slice"));
  EXPECT_TRUE(Has(ParseError(R"({"at": 0, "pick": {"x": 3, "sessionId": "s"}})"), "pick.sessionId: set by the player"));
  EXPECT_TRUE(Has(ParseError(R"({"at": 0, "pick": {"x": 3}, "slice": {"out": "a.png"}})"), "one event"));
  EXPECT_TRUE(Has(ParseError(R"({"at": 0, "pick": [1, 2]})"), "line 1: pick: must be an object"));
}

// examples/scripts/reading.jsonl, which docs/client.md and reading.md point to.
TEST(SessionScript, TheReadingExampleHasSlicesAndPicks) {
  const cli::SessionScript script =
      cli::LoadScript(std::filesystem::path(CINEVOL_SOURCE_DIR) / "examples" / "scripts" / "reading.jsonl");
  int slices = 0, picks = 0;
  for (const cli::ScriptStep& step : script.calls) slices += bool(step.call->slice), picks += bool(step.call->pick);
  EXPECT_EQ(slices, 4);
  EXPECT_EQ(picks, 4);
  EXPECT_EQ(script.steps.size(), 2u) << "two camera events";
}

// The loadtest scripts of bench/speed-run.sh (docs/performance.md): a view that
// stops and goes with interactive resolution, and a transfer-function drag.
TEST(SessionScript, TheBenchScriptsMoveAndRestAsTheirStepsSay) {
  const std::filesystem::path scenes = std::filesystem::path(CINEVOL_SOURCE_DIR) / "bench" / "scenes";
  const cli::SessionScript stop_and_go = cli::LoadScript(scenes / "stop-and-go.jsonl");
  EXPECT_EQ(stop_and_go.session.viewport.width(), 1280);
  EXPECT_EQ(stop_and_go.session.stream.interactive_frame_ms(), 33.0f);
  EXPECT_TRUE(stop_and_go.session.stream.frames_at_rendered_size());
  ASSERT_EQ(stop_and_go.steps.size(), 2u);
  EXPECT_TRUE(stop_and_go.steps[0].is_orbit);
  EXPECT_EQ(stop_and_go.steps[0].orbit.seconds, 1.0);
  EXPECT_EQ(stop_and_go.steps[1].at, 1.6) << "then at rest, past the 200 ms the view counts as moving";

  const cli::SessionScript drag = cli::LoadScript(scenes / "tf-drag.jsonl");
  ASSERT_TRUE(drag.session.scene.has_value());
  EXPECT_EQ(drag.session.stream.interactive_frame_ms(), 0.0f) << "full-size frames";
  ASSERT_EQ(drag.steps.size(), 31u);
  for (const cli::ScriptStep& step : drag.steps) EXPECT_TRUE(step.event.has_transfer_function()) << step.line;
  EXPECT_EQ(drag.steps.back().at, 1.0);
}

}  // namespace
}  // namespace cinevol::testing

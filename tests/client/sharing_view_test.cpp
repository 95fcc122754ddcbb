// What the viewer shows of a shared session, without a window: the line over
// the view for owner, presenter and viewer, the names the server writes for
// a grant's holder, and a pointer shared at most 20 times a second.
#include "viewer/sharing_view.h"

#include <gtest/gtest.h>

namespace cinevol::viewer {
namespace {

using namespace std::chrono_literals;

v1::SessionState State(const std::string& presenter, std::uint32_t viewers) {
  v1::SessionState s;
  s.set_presenter(presenter);
  s.set_viewers(viewers);
  return s;
}

void AddPointer(v1::SessionState& s, const std::string& who, float x, float y) {
  v1::SharedPointer* p = s.add_pointers();
  p->set_who(who);
  p->set_x(x);
  p->set_y(y);
}

TEST(SharingView, TheLineSaysWhoPresentsAndHowManyWatch) {
  EXPECT_EQ(PresenceLine(State("alice", 3), false, true), "Watching alice · 3 viewers");
  EXPECT_EQ(PresenceLine(State("alice", 1), false, true), "Watching alice · 1 viewer");
  EXPECT_EQ(PresenceLine(State("link g01", 2), true, true), "You present · 2 viewers");
  // The owner: nothing while nobody watches, then who presents.
  EXPECT_EQ(PresenceLine(State("alice", 0), true, false), "");
  EXPECT_EQ(PresenceLine(State("alice", 4), true, false), "Shared · 4 viewers");
  EXPECT_EQ(PresenceLine(State("bob", 4), false, false), "bob presents · 4 viewers (Share: Take back)");
}

TEST(SharingView, AGrantHolderIsNamedAsTheServerNamesIt) {
  const std::string secret = "cvg_g0123456789abcdef_00112233445566778899aabbccddeeff";
  EXPECT_EQ(GrantIdOf(secret), "g0123456789abcdef");
  EXPECT_EQ(GuessedHolderName(secret), "link g0123456789abcdef");
  EXPECT_EQ(GrantIdOf("not-a-grant"), "");
  EXPECT_EQ(GuessedHolderName("cvg_nokey"), "");
  v1::Grant link, user;
  link.set_id("g1");
  user.set_id("g2");
  user.set_principal("bob");
  EXPECT_EQ(HolderName(link), "link g1");
  EXPECT_EQ(HolderName(user), "bob");
}

// The echo of one's own pointer names one: but not where two pointers meet.
TEST(SharingView, ThePointersEchoNamesItsSender) {
  v1::SessionState s = State("alice", 2);
  AddPointer(s, "alice", 0.5f, 0.5f);
  AddPointer(s, "bob", 0.25f, 0.75f);
  EXPECT_EQ(EchoedName(s, 0.25f, 0.75f), "bob");
  EXPECT_EQ(EchoedName(s, 0.3f, 0.75f), std::nullopt);
  AddPointer(s, "carol", 0.25f, 0.75f);
  EXPECT_EQ(EchoedName(s, 0.25f, 0.75f), std::nullopt);
}

TEST(SharingView, ExpiryIsSaidInWords) {
  EXPECT_EQ(ExpiresIn(1000, 1000), "expired");
  EXPECT_EQ(ExpiresIn(1040, 1000), "in 40 s");
  EXPECT_EQ(ExpiresIn(1000 + 15 * 60, 1000), "in 15 min");
  EXPECT_EQ(ExpiresIn(1000 + 2 * 3600 + 5 * 60, 1000), "in 2 h 5 min");
  EXPECT_EQ(ExpiresIn(1000 + 7 * 86400, 1000), "in 7 d 0 h");
}

// At most one move per 50 ms, the newest of those waiting; a hidden pointer
// once the mouse leaves, and none before any was shown.
TEST(SharingView, APointerGoesAtMostTwentyTimesASecondAndHidesWhenTheMouseLeaves) {
  PointerShare share;
  const auto t0 = PointerShare::Clock::now();
  share.MoveTo(std::nullopt);
  EXPECT_FALSE(share.Due(t0)) << "nothing shown yet: nothing to hide";
  share.MoveTo(PointerShare::At{0.1f, 0.2f});
  const auto first = share.Due(t0);
  ASSERT_TRUE(first);
  EXPECT_FLOAT_EQ(first->x(), 0.1f);
  EXPECT_FALSE(first->hidden());
  share.MoveTo(PointerShare::At{0.3f, 0.3f});
  share.MoveTo(PointerShare::At{0.4f, 0.5f});
  EXPECT_FALSE(share.Due(t0 + 20ms)) << "too soon after the last";
  const auto newest = share.Due(t0 + 50ms);
  ASSERT_TRUE(newest);
  EXPECT_FLOAT_EQ(newest->x(), 0.4f);
  EXPECT_FLOAT_EQ(newest->y(), 0.5f);
  EXPECT_EQ(share.sent(), (PointerShare::At{0.4f, 0.5f}));
  EXPECT_FALSE(share.Due(t0 + 200ms)) << "no move, nothing to send";
  share.MoveTo(std::nullopt);
  const auto hidden = share.Due(t0 + 200ms);
  ASSERT_TRUE(hidden);
  EXPECT_TRUE(hidden->hidden());
  EXPECT_FALSE(share.sent());
  // Back where it was hidden from, before the hide went: nothing changes.
  share.MoveTo(PointerShare::At{0.6f, 0.6f});
  share.MoveTo(std::nullopt);
  EXPECT_FALSE(share.Due(t0 + 400ms));
}

}  // namespace
}  // namespace cinevol::viewer

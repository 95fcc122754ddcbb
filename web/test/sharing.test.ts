import assert from "node:assert/strict";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import { PointerSchema, SessionStateSchema } from "../gen/cinevol/v1/service_pb.js";
import { readAddress, shareLink, withoutToken } from "../src/address.js";
import type { Api } from "../src/api.js";
import { echoedName, fitted, fromFrame, othersPointers, Throttle, toFrame } from "../src/pointers.js";
import { LiveSession } from "../src/session.js";
import { expiresIn, holder, ownName, presence } from "../src/share.js";
import { MotionToPhoton } from "../src/stats.js";
import { shareWords } from "../src/words.js";

const SECRET = "cvg_g0123456789abcdef_00112233445566778899aabbccddeeff";

test("a share's link carries its secret in the fragment, which the page reads and then drops", () => {
  const link = shareLink("https://viewer.example.org:8443", SECRET);
  assert.equal(link, `https://viewer.example.org:8443/#grant=${SECRET}`);
  const url = new URL(link);
  assert.equal(url.search, "", "nothing of the secret in the query, so nothing reaches a server's log");
  assert.equal(readAddress(url.search, url.hash).grant, SECRET);
  assert.equal(withoutToken(url.pathname, url.search), "/");
  const withToken = readAddress("", `#grant=${SECRET}&token=bob-token`);
  assert.deepEqual([withToken.grant, withToken.token], [SECRET, "bob-token"], "a user's share: the grant and their token");
  assert.equal(readAddress(`?grant=${SECRET}`, "").grant, undefined, "a grant in the query is not read");
  assert.equal(readAddress("", "#grant=%20").grant, undefined);
});

test("the pointer as fractions of the frame shown, fitted whole in the view", () => {
  // A 400 x 300 frame in an 800 x 300 view: 200 pixels of black either side.
  const rect = fitted({ width: 800, height: 300 }, { width: 400, height: 300 });
  assert.deepEqual(rect, { left: 200, top: 0, width: 400, height: 300 });
  assert.deepEqual(toFrame({ x: 400, y: 150 }, rect), { x: 0.5, y: 0.5 });
  assert.deepEqual(toFrame({ x: 200, y: 0 }, rect), { x: 0, y: 0 });
  assert.equal(toFrame({ x: 199, y: 150 }, rect), null, "on the black beside the frame: no pointer");
  assert.equal(toFrame({ x: 600, y: 150 }, rect), null, "the right edge is outside");
  // A frame twice the view's size (device pixels): the same fractions.
  const hidpi = fitted({ width: 400, height: 300 }, { width: 800, height: 600 });
  assert.deepEqual(toFrame({ x: 100, y: 75 }, hidpi), { x: 0.25, y: 0.25 });
  // Someone else's pointer at a quarter across lands where that quarter shows on this view.
  assert.deepEqual(fromFrame({ x: 0.25, y: 0.5 }, rect), { x: 300, y: 150 });
  const tall = fitted({ width: 300, height: 800 }, { width: 300, height: 400 });
  assert.deepEqual(fromFrame({ x: 0.5, y: 0 }, tall), { x: 150, y: 200 });
});

test("pointer moves go at most once per 50 ms, the newest of them, and a hidden one is never lost", () => {
  let clock = 0;
  const sent: (string | null)[] = [], timers: { at: number; run: () => void }[] = [];
  const throttle = new Throttle<string | null>((v) => sent.push(v), 50, () => clock,
                                              (run, ms) => timers.push({ at: clock + ms, run }));
  const advance = (to: number) => {  // runs the timers due by then
    clock = to;
    const due = timers.filter((x) => x.at <= to);
    timers.splice(0, timers.length, ...timers.filter((x) => x.at > to));
    for (const t of due) t.run();
  };
  throttle.push("a");
  assert.deepEqual(sent, ["a"], "the first move goes at once");
  for (const [t, v] of [[10, "b"], [20, "c"], [30, "d"]] as const) {
    clock = t;
    throttle.push(v);
  }
  assert.deepEqual(sent, ["a"]);
  assert.equal(timers.length, 1, "one send waits");
  advance(50);
  assert.deepEqual(sent, ["a", "d"], "the newest of the moves in between");
  clock = 60;
  throttle.push(null);  // the pointer leaves the view
  advance(100);
  assert.deepEqual(sent, ["a", "d", null]);
  // Over a second of moves every 5 ms: about 20 sends, never more than one per 50 ms.
  sent.length = 0;
  for (let t = 200; t < 1200; t += 5) {
    advance(t);
    throttle.push(`m${t}`);
  }
  advance(1300);
  assert.ok(sent.length >= 19 && sent.length <= 21, `${sent.length} sends in a second`);
  assert.equal(sent[sent.length - 1], "m1195", "the last place arrives");
});

test("everyone's pointer but one's own; one's own name from the server's echo", () => {
  const pointers = [{ who: "alice", x: 0.25, y: 0.5 }, { who: "link g1", x: Math.fround(0.1), y: Math.fround(0.7) }];
  assert.deepEqual(othersPointers(pointers, "alice").map((p) => p.who), ["link g1"]);
  assert.equal(othersPointers(pointers, undefined).length, 2, "not knowing one's name: all are drawn");
  assert.equal(echoedName(pointers, { x: 0.1, y: 0.7 }), "link g1", "the server keeps floats: 0.1 comes back as float32");
  assert.equal(echoedName(pointers, { x: 0.1, y: 0.71 }), undefined);
  assert.equal(echoedName(pointers, undefined), undefined);
});

test("one's own name: the owner's principal, a link's holder from its secret", () => {
  assert.equal(ownName("alice", ""), "alice");
  assert.equal(ownName(undefined, ""), undefined);
  assert.equal(ownName("alice", SECRET), "link g0123456789abcdef");
  assert.equal(ownName(undefined, "not-a-secret"), undefined);
  assert.equal(holder({ id: "g0123456789abcdef", principal: "" }), "link g0123456789abcdef", "as the server names it");
  assert.equal(holder({ id: "g1", principal: "bob" }), "bob");
});

test("the line over the view: who presents and how many watch", () => {
  assert.equal(presence({ presenter: "alice", viewers: 2 }, "link g1", true), "Watching alice · 2 viewers");
  assert.equal(presence({ presenter: "link g1", viewers: 1 }, "link g1", true), "You present · 1 viewer");
  assert.equal(presence({ presenter: "alice", viewers: 0 }, "alice", false), "", "one's own session, unwatched: nothing");
  assert.equal(presence({ presenter: "alice", viewers: 3 }, "alice", false), "Shared · 3 viewers");
  assert.equal(presence({ presenter: "bob", viewers: 3 }, "alice", false), "bob presents · 3 viewers");
});

test("a grant's expiry in words", () => {
  assert.equal(expiresIn(1000, 1000), "expired");
  assert.equal(expiresIn(1040, 1000), "in 40 s");
  assert.equal(expiresIn(1000 + 15 * 60, 1000), "in 15 min");
  assert.equal(expiresIn(1000 + 2 * 3600 - 1, 1000), "in 2 h 0 min");
  assert.equal(expiresIn(1000 + 26 * 3600, 1000), "in 1 d 2 h");
});

test("a revoked or expired share, and a user's share without its token, in plain words", () => {
  const revoked = shareWords(new ConnectError("grant g1 was revoked by the session's owner", Code.PermissionDenied));
  assert.match(revoked, /share has ended.*revoked.*\(grant g1 was revoked by the session's owner\)/);
  assert.match(shareWords(new ConnectError("grant g1 expired", Code.PermissionDenied)), /expired/);
  assert.match(shareWords(new ConnectError("no token", Code.Unauthenticated)), /your own token/);
  assert.match(shareWords(new ConnectError("down", Code.Unavailable)), /cannot be reached/, "the rest as for one's own");
});

/** A server that answers a share's calls as cinevol-server does, recording them. */
function fakeServer(watch: (signal: AbortSignal) => AsyncIterable<unknown>, send: () => Promise<unknown>) {
  const calls: { method: string; request: Record<string, unknown> }[] = [];
  const api = {
    sessionAddress: "",
    sessions: {
      watchSession: (request: Record<string, unknown>, options: { signal: AbortSignal }) => {
        calls.push({ method: "watchSession", request });
        return watch(options.signal);
      },
      sendEvents: (request: Record<string, unknown>) => {
        calls.push({ method: "sendEvents", request });
        return send();
      },
      closeSession: async (request: Record<string, unknown>) => { calls.push({ method: "closeSession", request }); },
      createSession: async (request: Record<string, unknown>) => { calls.push({ method: "createSession", request }); },
    },
  };
  return { api: api as unknown as Api, calls };
}

function handlersFor(seen: { refused: string[][]; failed: { text: string; code?: Code }[]; states: number }) {
  return {
    attached: () => {}, frame: () => {}, notice: () => {}, banner: () => {},
    state: () => { seen.states += 1; },
    refused: (kinds: string[]) => { seen.refused.push(kinds); },
    failed: (text: string, code?: Code) => { seen.failed.push({ text, code }); },
  };
}

const settle = () => new Promise((r) => setTimeout(r, 20));

test("a share's session: its grant in every call, pointers outside the frames' numbering, never closed by a viewer", async () => {
  const state = { kind: { case: "state", value: create(SessionStateSchema, { presenter: "alice", viewers: 1 }) } };
  let refusePointer = false;
  const { api, calls } = fakeServer(async function* (signal) {
    yield state;
    await new Promise((r) => signal.addEventListener("abort", r));
  }, async () => {
    if (refusePointer) throw new ConnectError("pointer: grant g1 does not share its holder's pointer", Code.PermissionDenied);
    return { state: undefined };
  });
  const seen = { refused: [] as string[][], failed: [] as { text: string; code?: Code }[], states: 0 };
  const session = LiveSession.watchShared(api, handlersFor(seen), new MotionToPhoton(), SECRET);
  await settle();
  assert.equal(seen.states, 1);
  assert.deepEqual(calls[0], { method: "watchSession", request: { sessionId: "", grant: SECRET } });
  session.post({ case: "pointer", value: create(PointerSchema, { x: 0.5, y: 0.25 }) });
  await settle();
  const sent = calls.find((c) => c.method === "sendEvents")!.request;
  assert.equal(sent.grant, SECRET);
  assert.equal(session.lastSeq, 0n, "a pointer is not an event a frame answers");
  assert.deepEqual(session.sentKinds, { pointer: 1 });
  refusePointer = true;
  session.post({ case: "pointer", value: create(PointerSchema, { hidden: true }) });
  await settle();
  assert.deepEqual(seen.refused, [["pointer"]], "a refused pointer is told as such; the watch goes on");
  assert.equal(seen.failed.length, 0);
  session.close();
  await settle();
  assert.ok(!calls.some((c) => c.method === "closeSession"), "a viewer leaving does not end the owner's session");
});

test("a SendEvents answer taken before a hand-over does not bring the old presenter back", async () => {
  let handOver: () => void = () => {};
  const { api } = fakeServer(async function* (signal) {
    yield { kind: { case: "state", value: create(SessionStateSchema, { presenter: "alice", viewers: 1 }) } };
    await new Promise<void>((r) => { handOver = r; });
    yield { kind: { case: "state", value: create(SessionStateSchema, { presenter: "link g1", viewers: 1 }) } };
    await new Promise((r) => signal.addEventListener("abort", r));
  }, async () => {
    handOver();  // the stream says "link g1" while this answer, taken before, is on its way
    await settle();
    return { state: create(SessionStateSchema, { presenter: "alice", viewers: 1, lastEventSeq: 1n }) };
  });
  const seen = { refused: [] as string[][], failed: [] as { text: string; code?: Code }[], states: 0 };
  const session = LiveSession.watchShared(api, handlersFor(seen), new MotionToPhoton(), SECRET);
  await settle();
  session.post({ case: "pointer", value: create(PointerSchema, { x: 0.5, y: 0.5 }) });
  await settle();
  await settle();
  assert.equal(session.state?.presenter, "link g1", "the stream's newer presenter stands");
  assert.equal(session.state?.lastEventSeq, 1n, "the answer's own part is taken");
  session.close();
});

test("a revoked share ends the watch in plain words, with no new session made from it", async () => {
  const { api, calls } = fakeServer(async function* () {
    yield { kind: { case: "state", value: create(SessionStateSchema, { presenter: "alice", viewers: 1 }) } };
    throw new ConnectError("grant g1 was revoked by the session's owner", Code.PermissionDenied);
  }, async () => ({}));
  const seen = { refused: [] as string[][], failed: [] as { text: string; code?: Code }[], states: 0 };
  LiveSession.watchShared(api, handlersFor(seen), new MotionToPhoton(), SECRET);
  await settle();
  assert.equal(seen.failed.length, 1);
  assert.match(seen.failed[0].text, /share has ended: its owner revoked it.*grant g1 was revoked/);
  assert.equal(seen.failed[0].code, Code.PermissionDenied);
  assert.deepEqual(calls.map((c) => c.method), ["watchSession"], "no retry, no CreateSession");
});

test("a share's session that ended on the server is not made again as one's own", async () => {
  const { api, calls } = fakeServer(async function* () {
    yield* [];
    throw new ConnectError("grant g1: its session has ended", Code.NotFound);
  }, async () => ({}));
  const seen = { refused: [] as string[][], failed: [] as { text: string; code?: Code }[], states: 0 };
  LiveSession.watchShared(api, handlersFor(seen), new MotionToPhoton(), SECRET);
  await settle();
  assert.match(seen.failed[0]?.text ?? "", /shared session ended on the server/);
  assert.ok(!calls.some((c) => c.method === "createSession"));
});

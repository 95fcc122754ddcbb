// The DICOMweb origin's rendered resources (gateway/rendered.ts) and their signed URLs (gateway/signed_urls.ts):
// what is refused before anything is loaded, an MPR's plane and size, and a signed URL served as its caller only
// for its resource and only until it expires, against an in-memory server.
import assert from "node:assert/strict";
import { test } from "node:test";
import { Code, ConnectError, createRouterTransport } from "@connectrpc/connect";
import { PacsService, ServerService, SessionService } from "../gen/cinevol/v1/service_pb.js";
import { assemble, centreIn, decodePng, encodePng, fitPng } from "../gateway/png.js";
import { deflateSync } from "node:zlib";
import {
  answerRendered, planMpr, readRendered, Refusal, scopeOf, type Placement, type RenderedRequest,
} from "../gateway/rendered.js";
import { RenderQueue } from "../gateway/render_queue.js";
import { answerSigning, readSigningRequest, SignedUrls, DEFAULT_LIMITS } from "../gateway/signed_urls.js";

const SERIES = "/dicom-web/main/studies/1.2.3/series/1.2.3.4";
const VIEW = "viewpointposition=0,-500,0&viewpointlookat=0,0,0&viewpointup=0,0,1";

/** The refusal `readRendered` throws for a URL, as status and message. */
function refusal(url: string, accept?: string): { status: number; message: string } {
  const [path, search = ""] = url.split("?");
  try {
    readRendered(path, search, accept);
  } catch (e) {
    if (e instanceof Refusal) return { status: e.status, message: e.message };
    throw e;
  }
  assert.fail(`${url} was not refused`);
}

test("bad parameters are refused with the standard's status and a message, before anything is loaded", () => {
  const cases: [string, number, RegExp][] = [
    [`${SERIES}/rendered3D?renderingmethod=raytraced`, 400, /renderingmethod: 'raytraced' is not/],
    [`${SERIES}/rendered3D?viewpointposition=NaN,0,0&viewpointlookat=0,0,0`, 400, /viewpointposition: 'NaN,0,0'/],
    [`${SERIES}/rendered3D?viewpointposition=1e400,0,0&viewpointlookat=0,0,0`, 400, /viewpointposition/],
    [`${SERIES}/rendered3D?viewport=1000000,1000000`, 400, /viewport: each side a whole number in \[1, 4096\]/],
    [`${SERIES}/rendered3D?viewport=512`, 400, /viewport: '512' is not 2 numbers/],
    [`${SERIES}/renderedmpr?${VIEW}&mprslab=1e6`, 400, /mprslab: a thickness in mm, 0 to 1e4/],
    [`${SERIES}/renderedmpr?${VIEW}&mprslab=NaN`, 400, /mprslab/],
    [`${SERIES}/rendered3D?quality=0`, 400, /quality: 1 to 100/],
    [`${SERIES}/rendered3D?orientation=x`, 400, /orientation/],
    [`${SERIES}/renderedmpr?${VIEW}&window=400,40,sigmoid`, 400, /window: '400,40,sigmoid'/],
    [`${SERIES}/renderedmpr?${VIEW}&accept=image/jpeg`, 406, /offered for an MPR or a frame: image\/png/],
    ["/dicom-web/http://127.0.0.1:9/pacs/studies/1.2/series/1.2/rendered3D", 400, /pacs: 'http:\/\/127\.0\.0\.1:9\/pacs' is not a PACS name/],
    ["/dicom-web/http%3A%2F%2F10.0.0.1%2F/studies/1.2/series/1.2/rendered3D", 400, /pacs: .* never an address/],
    ["/dicom-web/main/studies/1.2/series/1.2';--/rendered3D", 400, /UID is digits and dots/],
    ["/dicom-web/main/studies/1.2/series/1.2/thumbnail", 404, /is not a rendered resource/],
    ["/dicom-web/", 404, /is not a rendered resource/],
  ];
  for (const [url, status, said] of cases) {
    const got = refusal(url);
    assert.equal(got.status, status, `${url}: ${got.message}`);
    assert.match(got.message, said, url);
  }
  assert.equal(readRendered("/index.html", ""), undefined, "the page's own paths are not the origin's");
  const long = `/dicom-web/${"x/studies/1/series/".repeat(800)}rendered3`;  // 16 KB, as large as node lets a URL be
  const started = performance.now();
  assert.equal(refusal(long).status, 404);
  assert.ok(performance.now() - started < 100, "a long path is refused in linear time");
});

test("a swivel is a video (video/mp4): its range, step and rate read, and what cannot be one refused", () => {
  const swivel = (query: string, accept?: string) => readRendered(`${SERIES}/rendered3D`, query, accept)!;
  const turn = swivel("swivelrange=90&animationstepsize=30&animationrate=10&viewport=64,48");
  assert.equal(turn.accept, "video/mp4", "a swivel's default media type");
  assert.deepEqual(turn.swivel, { degrees: 90, stepDegrees: 30, rate: 10 });
  assert.deepEqual(swivel("swivelrange=-360", "video/*").swivel, { degrees: -360, stepDegrees: 2, rate: 25 });
  assert.equal(swivel("", "image/jpeg").swivel, undefined, "a still has none");
  const cases: [string, string | undefined, number, RegExp][] = [
    ["accept=video/mp4", undefined, 400, /swivelrange: a video of a rendered volume is a swivel/],
    ["swivelrange=90&accept=image/png", undefined, 406, /offered for a swivel animation: video\/mp4/],
    ["swivelrange=NaN", undefined, 400, /swivelrange: degrees/],
    ["swivelrange=0", undefined, 400, /swivelrange: degrees, non-zero/],
    ["swivelrange=360&animationstepsize=0.01", undefined, 400, /36000 frames; at most 3600/],
    ["swivelrange=360&animationrate=120", undefined, 400, /animationrate: frames a second, 1 to 60/],
    ["animationrate=10", undefined, 400, /animationrate: says how a swivel animates; give swivelrange too/],
    ["swivelrange=90&viewport=63,48", undefined, 400, /viewport: a swivel's video needs each side even/],
  ];
  for (const [query, accept, status, said] of cases) {
    const got = refusal(`${SERIES}/rendered3D?${query}`, accept);
    assert.equal(got.status, status, `${query}: ${got.message}`);
    assert.match(got.message, said, query);
  }
  assert.match(refusal(`${SERIES}/renderedmpr?${VIEW}&swivelrange=90`).message, /an MPR does not swivel|video\/mp4/);
});

test("an MPR is PNG: the default, a wildcard or PNG among the types asked", () => {
  const accept = (header?: string) => readRendered(`${SERIES}/renderedmpr`, VIEW, header)!.accept;
  assert.equal(accept(), "image/png");
  assert.equal(accept("*/*"), "image/png");
  assert.equal(accept("image/jpeg, image/png;q=0.5"), "image/png");
  assert.equal(refusal(`${SERIES}/renderedmpr?${VIEW}`, "image/jpeg").status, 406);
  assert.equal(readRendered(`${SERIES}/rendered3D`, "")!.accept, "image/jpeg", "a 3D view stays JPEG by default");
});

test("a rendered frame names one frame of an image, its window and viewport; a view's parameters are refused", () => {
  const instance = `${SERIES}/instances/1.2.3.4.5`;
  const frame = readRendered(`${instance}/frames/3/rendered`, "window=40,400,linear&viewport=64,32")!;
  assert.equal(frame.kind, "renderedframe");
  assert.deepEqual(frame.frame, { instanceUid: "1.2.3.4.5", number: 3 });
  assert.deepEqual(frame.window, { center: 40, width: 400 });
  assert.deepEqual([frame.viewport, frame.viewportGiven, frame.accept], [{ width: 64, height: 32 }, true, "image/png"]);
  assert.deepEqual(readRendered(`${instance}/rendered`, "")!.frame, { instanceUid: "1.2.3.4.5", number: 0 },
                   "the instance itself: frame 0, a single-frame image's");
  assert.equal(scopeOf(frame), `${instance}/frames/3/rendered`);
  assert.equal(scopeOf(readRendered(`${instance}/rendered`, "")!), `${instance}/rendered`);
  const cases: [string, number, RegExp][] = [
    [`${instance}/frames/1,2/rendered`, 406, /multi-frame media type/],
    [`${instance}/frames/0/rendered`, 400, /frame numbers from 1/],
    [`${instance}/frames/99999999999999999999/rendered`, 400, /frame numbers from 1/],
    [`${instance}/frames/1/rendered?mprslab=10`, 400, /mprslab: says a view of a volume/],
    [`${instance}/frames/1/rendered?viewpointposition=0,0,1`, 400, /viewpointposition: says a view/],
    [`${instance}/frames/1/rendered?window=40,400,sigmoid`, 400, /window: '40,400,sigmoid'/],
    [`${instance}/frames/1/rendered?accept=image/jpeg`, 406, /offered for an MPR or a frame: image\/png/],
    [`${instance}/frames/a/rendered`, 400, /frames: a number/],
  ];
  for (const [url, status, said] of cases) {
    const got = refusal(url);
    assert.equal(got.status, status, `${url}: ${got.message}`);
    assert.match(got.message, said, url);
  }
});

// 100 x 80 x 20 voxels of 1 x 1 x 2 mm, index axes along the patient's: x 0..99, y 0..79, z 0..38 mm.
const BOX: Placement = { direction: [1, 0, 0, 0, 1, 0, 0, 0, 1], originMm: [0, 0, 0], spacingMm: [1, 1, 2],
                         dims: [100, 80, 20] };
const mpr = (query: string) => readRendered(`${SERIES}/renderedmpr`, query) as RenderedRequest;
const near = (a: number[], b: number[]) => a.every((v, i) => Math.abs(v - b[i]) < 1e-9);

test("an MPR's plane: through the look-at point across the view, rows along the view's right", () => {
  // From in front of the patient (anterior, -y) looking back, the head up: a coronal plane, the patient's left on
  // the image's right (+x).
  const plan = planMpr(mpr("viewpointposition=50,-500,19&viewpointlookat=50,40,19&viewpointup=0,0,1"), BOX);
  assert.ok(near(plan.normal, [0, 1, 0]) && near(plan.row, [1, 0, 0]), JSON.stringify(plan));
  assert.deepEqual(plan.point, [50, 40, 19]);
  assert.equal(plan.pixelMm, 0, "no viewport: the volume's own resolution");
  assert.throws(() => planMpr(mpr("viewpointposition=0,0,0&viewpointlookat=0,0,0"), BOX), /one point/);
  assert.throws(() => planMpr(mpr("viewpointposition=0,0,-9&viewpointlookat=0,0,0&viewpointup=0,0,1"), BOX),
                /viewpointup lies along the view/);
});

test("an MPR with a viewport: the server's own pixels where they fit it exactly, else the section fitted", () => {
  const view = "viewpointposition=50,-500,19&viewpointlookat=50,40,19&viewpointup=0,0,1";
  // The coronal section is 99 x 38 mm between its outermost voxel centres: 100 x 39 pixels of 1 mm.
  assert.equal(planMpr(mpr(`${view}&viewport=100,39`), BOX).pixelMm, 0);
  // 50 x 50: the width limits, 99 mm over 49 pixel steps; 30 x 300: the height, 38 mm over 29.
  assert.ok(Math.abs(planMpr(mpr(`${view}&viewport=50,50`), BOX).pixelMm - 99 / 49) < 1e-9);
  assert.ok(Math.abs(planMpr(mpr(`${view}&viewport=300,30`), BOX).pixelMm - 38 / 29) < 1e-9);
  assert.ok(Math.abs(planMpr(mpr(`${view}&viewport=1,1`), BOX).pixelMm - 99) < 1e-9);
});

test("a slab thicker than the volume projects all of it: cut to what the volume reaches, and said", () => {
  const view = "viewpointposition=50,-500,19&viewpointlookat=50,40,19&viewpointup=0,0,1";
  assert.equal(planMpr(mpr(`${view}&mprslab=20`), BOX).slabNote, undefined);
  const whole = planMpr(mpr(`${view}&mprslab=5000`), BOX);
  // The volume lies 40 mm behind and 39 mm in front of the plane; a voxel (2 mm) more on each side.
  assert.equal(whole.slabMm, 2 * (40 + 2));
  assert.match(whole.slabNote!, /mprslab: 5000 mm reaches past the volume, which lies within 40\.0 mm of the plane/);
});

test("a slice is centred in the viewport: bordered in black where smaller, cropped evenly where larger", () => {
  const image = { width: 3, height: 2, channels: 3, pixels: Uint8Array.from({ length: 18 }, (_, i) => i + 1) };
  const round = decodePng(encodePng(image));
  assert.deepEqual({ ...round, pixels: [...round.pixels] }, { ...image, pixels: [...image.pixels] });
  const bordered = centreIn(image, 5, 4);
  assert.deepEqual([...bordered.pixels.subarray(0, 15)], Array(15).fill(0), "the top row is border");
  assert.deepEqual([...bordered.pixels.subarray(18, 27)], [1, 2, 3, 4, 5, 6, 7, 8, 9], "row 1 from column 1");
  assert.deepEqual([...centreIn(image, 1, 1).pixels], [4, 5, 6], "the middle pixel of the top row");
});

test("a PNG fitted off the event loop is the same picture centred; every row filter is undone", async () => {
  const image = { width: 3, height: 2, channels: 3, pixels: Uint8Array.from({ length: 18 }, (_, i) => 10 * i) };
  const fitted = decodePng(await fitPng(encodePng(image), 5, 4));
  assert.deepEqual([...fitted.pixels], [...centreIn(image, 5, 4).pixels]);
  // The 2 x 2 RGB picture [[1 2 3, 4 5 6], [7 8 9, 10 11 12]] with its rows filtered sub then up, and average then
  // Paeth: each filter byte, then the row less its predictor.
  const filtered = (raw: number[]) => assemble({ width: 2, height: 2, channels: 3 }, deflateSync(Buffer.from(raw)));
  for (const raw of [[1, 1, 2, 3, 3, 3, 3, 2, 6, 6, 6, 6, 6, 6], [3, 1, 2, 3, 4, 4, 5, 4, 6, 6, 6, 3, 3, 3]]) {
    assert.deepEqual([...decodePng(filtered(raw)).pixels], [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12], `${raw}`);
  }
});

test("a signed URL stands for its caller at its resource until it expires; others are refused", () => {
  let now = 1_000_000;
  const urls = new SignedUrls(DEFAULT_LIMITS, () => now);
  const scope = `${SERIES}/rendered3D`;
  const { capability, expiresAtMs } = urls.issue("Bearer alice-token", scope, 60);
  assert.match(capability, /^[A-Za-z0-9_-]{43}$/, "256 random bits, URL-safe");
  assert.ok(!capability.includes("alice"));
  assert.equal(expiresAtMs, now + 60_000);
  assert.equal(urls.redeem(capability, scope), "Bearer alice-token");
  const refused = (cap: string, at: string) => {
    try {
      urls.redeem(cap, at);
    } catch (e) {
      return e as Refusal;
    }
    assert.fail("not refused");
  };
  assert.equal(refused(capability, `${SERIES}/renderedmpr`).status, 403);
  assert.equal(refused(capability, "/dicom-web/main/studies/1.2.3/series/9.9/rendered3D").status, 403);
  // One character changed: the last carries 4 of the 256 bits, so it is "A" one time in 16.
  const forged = capability.slice(0, -1) + (capability.endsWith("A") ? "B" : "A");
  assert.equal(refused(forged, scope).status, 401, "a forged one");
  now += 60_000;
  const expired = refused(capability, scope);
  assert.equal(expired.status, 401);
  assert.match(expired.message, /expired at/);
  assert.equal(urls.size, 0, "an expired one is dropped");
});

test("signed URLs are bounded: per token and overall, expired ones no longer counted", () => {
  let now = 0;
  const urls = new SignedUrls({ ...DEFAULT_LIMITS, maxAlive: 3, maxAlivePerToken: 2 }, () => now);
  urls.issue("Bearer a", "s", 10);
  urls.issue("Bearer a", "s", 20);
  assert.throws(() => urls.issue("Bearer a", "s", 10), (e: Refusal) => e.status === 429 && /this token holds 2/.test(e.message));
  urls.issue("Bearer b", "s", 10);
  assert.throws(() => urls.issue("Bearer c", "s", 10), (e: Refusal) => e.status === 429 && /gateway holds 3/.test(e.message));
  now = 10_000;  // a's first and b's expire
  urls.issue("Bearer a", "s", 10);
  urls.issue("Bearer c", "s", 10);
  assert.equal(urls.size, 3);
});

test("a signing request names a rendered resource by path and whole seconds within the limit", () => {
  const ok = readSigningRequest(JSON.stringify({ url: `${SERIES}/rendered3d?viewport=64,64`, expiresIn: 300 }),
                                DEFAULT_LIMITS);
  assert.deepEqual(ok, { url: `${SERIES}/rendered3d?viewport=64,64`, scope: `${SERIES}/rendered3D`, lifetimeS: 300 });
  assert.equal(readSigningRequest(JSON.stringify({ url: `${SERIES}/rendered3D` }), DEFAULT_LIMITS).lifetimeS, 60);
  for (const [body, said] of [
    ["{", /not JSON/],
    [JSON.stringify({ url: `http://127.0.0.1:1${SERIES}/rendered3D` }), /no scheme or host/],
    [JSON.stringify({ url: `${SERIES}/rendered3D`, expiresIn: 301 }), /expiresIn: whole seconds, 1 to 300/],
    [JSON.stringify({ url: `${SERIES}/rendered3D`, expiresIn: 0.5 }), /expiresIn/],
    [JSON.stringify({ url: `${SERIES}/rendered3D?signature=x` }), /already carries a signature/],
    [JSON.stringify({ url: `${SERIES}/rendered3D?viewport=0,0` }), /url: viewport/],
    [JSON.stringify({ url: "/dicom-web/signed-url" }), /url: .* is not a rendered resource/],
  ] as [string, RegExp][]) {
    assert.throws(() => readSigningRequest(body, DEFAULT_LIMITS), (e: Refusal) => e.status === 400 && said.test(e.message),
                  body);
  }
});

/** A server in memory: alice's token is known; a still is the caller's token as text. */
const server = () => createRouterTransport((router) => {
  const caller = (headers: Headers) => {
    const token = headers.get("authorization");
    if (token !== "Bearer alice-token") throw new ConnectError("the bearer token is not valid", Code.Unauthenticated);
    return token;
  };
  router.service(ServerService, { getStatus: (_, ctx) => (caller(ctx.requestHeader), {}) });
  router.service(PacsService, {
    async *loadSeries(_, ctx) {
      caller(ctx.requestHeader);
      yield { update: { case: "volume", value: { id: "pacs-volume" } } };
    },
  });
  router.service(SessionService, {
    createSession: (_, ctx) => (caller(ctx.requestHeader), { sessionId: "s1" }),
    snapshot: (_, ctx) => ({ image: Buffer.from(`still for ${caller(ctx.requestHeader)}`) }),
    closeSession: () => ({}),
  });
});

interface Answer { status: number; headers: Record<string, string | number>; body: string }

/** A node-like request and a response that resolves with what was answered. */
function exchange(method: string, url: string, headers: Record<string, string>, body = "") {
  let done!: (a: Answer) => void;
  const answered = new Promise<Answer>((r) => { done = r; });
  let status = 0, sent: Record<string, string | number> = {};
  const res = {
    writableEnded: false,
    writeHead: (s: number, h: Record<string, string | number>) => { status = s; sent = h; },
    end(b: Buffer | string) { this.writableEnded = true; done({ status, headers: sent, body: String(b) }); },
  };
  const req = { url, method, headers, on: () => req, async *[Symbol.asyncIterator]() { yield Buffer.from(body); } };
  return { req, res, answered };
}

test("through the gateway's handlers: a signed URL is made for a valid token and served with no header", async () => {
  const transport = server(), urls = new SignedUrls();
  const sign = async (authorization: string, asked: object) => {
    const { req, res, answered } = exchange("POST", "/dicom-web/signed-url", { authorization }, JSON.stringify(asked));
    assert.ok(answerSigning(transport, urls, req, res));
    return answered;
  };
  const get = async (url: string, headers: Record<string, string> = {}) => {
    const { req, res, answered } = exchange("GET", url, headers);
    assert.ok(answerRendered(transport, req, res, new RenderQueue(), urls));
    return answered;
  };
  const made = await sign("Bearer alice-token", { url: `${SERIES}/rendered3D?viewport=64,48`, expiresIn: 30 });
  assert.equal(made.status, 200, made.body);
  const { url, expiresIn } = JSON.parse(made.body) as { url: string; expiresIn: number };
  assert.equal(expiresIn, 30);
  assert.ok(url.startsWith(`${SERIES}/rendered3D?viewport=64,48&signature=`) && !url.includes("alice"), url);
  const still = await get(url);
  assert.equal(still.status, 200, still.body);
  assert.equal(still.body, "still for Bearer alice-token", "served as alice");
  assert.equal((await get(url.replace("viewport=64,48", "viewport=32,32"))).status, 200, "its query may differ");
  assert.equal((await get(url.replace("rendered3D", "renderedmpr") + `&${VIEW}`)).status, 403);
  assert.equal((await get(url.replace(/signature=.*/, "signature=forged"))).status, 401);
  assert.equal((await get(url, { authorization: "Bearer alice-token" })).status, 400, "a signature or a header");
  assert.equal((await sign("Bearer mallory", { url: `${SERIES}/rendered3D` })).status, 401, "a token the server refuses");
  assert.equal(urls.size, 1, "nothing held for a refused token");
  const unsigned = exchange("POST", "/dicom-web/signed-url", {}, JSON.stringify({ url: `${SERIES}/rendered3D` }));
  answerSigning(transport, urls, unsigned.req, unsigned.res);
  assert.equal((await unsigned.answered).status, 401);
  const fetched = exchange("GET", "/dicom-web/signed-url", { authorization: "Bearer alice-token" });
  answerSigning(transport, urls, fetched.req, fetched.res);
  assert.equal((await fetched.answered).status, 405);
  assert.equal(scopeOf(readRendered(`${SERIES}/rendered3d`, "")!), `${SERIES}/rendered3D`);
});

test("rendered requests wait their turn: a caller's burst is held to its share, callers served in turn", async () => {
  const queue = new RenderQueue({ perCaller: 2, atOnce: 3, waitingPerCaller: 3, waiting: 8 });
  const turn = () => new Promise((r) => setImmediate(r));
  const started: string[] = [], release: (() => void)[] = [];
  const ask = (who: string, signal = new AbortController().signal) => queue.run(`Bearer ${who}`, signal, () => {
    started.push(who);
    return new Promise<string>((done) => release.push(() => done(who)));
  });
  const burst = [1, 2, 3, 4, 5].map(() => ask("alice"));
  await turn();
  assert.deepEqual(started, ["alice", "alice"], "two of alice's at once, her share");
  const gone = new AbortController();
  const bob = ask("bob"), carol = ask("carol", gone.signal);
  await turn();
  assert.deepEqual(started, ["alice", "alice", "bob"], "bob at once beside her, in the third slot");
  const overflow = await ask("alice").then(() => 0, (e: Refusal) => e.status);
  assert.equal(overflow, 429, "alice's sixth waits in no line: hers holds three");
  gone.abort();
  assert.equal(await carol.then(() => 0, (e: Refusal) => e.status), 499, "carol left before her turn");
  release.shift()!();  // one of alice's ends: her next starts (bob's slot stays his)
  await turn();
  assert.deepEqual(started.slice(3), ["alice"]);
  while (release.length) {
    release.shift()!();
    await turn();
  }
  assert.deepEqual(await Promise.all([...burst, bob]), ["alice", "alice", "alice", "alice", "alice", "bob"]);
  assert.deepEqual(queue.counts, { running: 0, waiting: 0 });
});

test("callers waiting are served in turn, one request each", async () => {
  const queue = new RenderQueue({ perCaller: 1, atOnce: 1, waitingPerCaller: 10, waiting: 100 });
  const order: string[] = [], release: (() => void)[] = [];
  const ask = (who: string) => queue.run(who, new AbortController().signal, () => {
    order.push(who);
    return new Promise<void>((done) => release.push(done));
  });
  const all = [ask("a"), ask("a"), ask("a"), ask("b"), ask("c")];
  while (order.length < 5) {
    await new Promise((r) => setImmediate(r));
    release.shift()?.();
  }
  await Promise.all(all);
  assert.deepEqual(order, ["a", "a", "b", "c", "a"], "after a's first, a, b and c take turns in the order they came");
});

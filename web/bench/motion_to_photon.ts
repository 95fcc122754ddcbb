// The browser's path without a browser (issue 61, docs/performance.md): a
// node client that talks as the page does (gRPC-web over HTTP/1.1,
// WatchSession for the frames, SendEvents for the events) through
// cinevol-web, and the same client straight to cinevol-server (gRPC over
// HTTP/2). Each path gets a session of its own on the same volume and scene
// and an orbit of camera events at RATE a second for SECONDS. An event's
// motion-to-photon here is the time from its send to the whole arrival of
// the first frame that applies it (frame.lastEventSeq at or past its seq);
// the page adds its decode and draw to that (bench/web-view.mjs measures
// those in Chromium). The gateway's added latency is the difference of the
// two paths' medians. Prints a line per path and one JSON line.
//   node motion-to-photon.mjs --gateway HOST:PORT --server HOST:PORT --volume ID --scene S.json
//        [--seconds 10] [--rate 30] [--width 1280] [--height 720] [--stream JSON]
import { readFileSync } from "node:fs";
import { parseArgs } from "node:util";
import { create, fromJson } from "@bufbuild/protobuf";
import { createClient, type Client } from "@connectrpc/connect";
import { createGrpcTransport, createGrpcWebTransport } from "@connectrpc/connect-node";
import { SceneSchema, type Camera, type Vec3 } from "../gen/cinevol/v1/scene_pb.js";
import { SessionEventSchema, SessionService, StreamSettingsSchema } from "../gen/cinevol/v1/service_pb.js";

const { values: o } = parseArgs({ options: {
  gateway: { type: "string" }, server: { type: "string" }, volume: { type: "string" }, scene: { type: "string" },
  seconds: { type: "string", default: "10" }, rate: { type: "string", default: "30" },
  width: { type: "string", default: "1280" }, height: { type: "string", default: "720" },
  stream: { type: "string", default: "{}" },
} });
if (!o.gateway || !o.server || !o.volume || !o.scene) {
  throw new Error("usage: --gateway HOST:PORT --server HOST:PORT --volume ID --scene S.json [--seconds S] [--rate HZ]");
}
const seconds = Number(o.seconds), rate = Number(o.rate);
const sceneJson = JSON.parse(readFileSync(o.scene, "utf8"));
delete sceneJson.volume;  // volumeId says which
const scene = fromJson(SceneSchema, sceneJson);
if (!(seconds > 0 && seconds <= 600 && rate > 0 && rate <= 240)) throw new Error("--seconds (0, 600], --rate (0, 240]");

interface PathFigures { path: string; device: string; events: number; answered: number; p50: number; p95: number; max: number;
                        sendP50: number; fps: number; mbps: number }

const percentile = (sorted: number[], q: number) =>
  sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] : NaN;

// `eye` turned about `target` by `radians` around the z axis (the volume-centred frame's superior).
function orbited(camera: Camera, radians: number): Camera {
  const eye = camera.eye!, target = camera.target!;
  const dx = eye.x - target.x, dy = eye.y - target.y, c = Math.cos(radians), s = Math.sin(radians);
  const turned: Vec3 = { ...eye, x: target.x + c * dx - s * dy, y: target.y + s * dx + c * dy };
  return { ...camera, eye: turned };
}

// One session through `sessions`: attach, orbit, measure, close. Bounded by SECONDS plus a grace for the last answers.
async function measure(path: string, sessions: Client<typeof SessionService>): Promise<PathFigures> {
  const created = await sessions.createSession({
    volumeId: o.volume, viewport: { width: Number(o.width), height: Number(o.height) },
    initial: { case: "scene", value: scene },
    stream: fromJson(StreamSettingsSchema, JSON.parse(o.stream!)),
  });
  const sessionId = created.sessionId;
  const abort = new AbortController();
  const sentAt = new Map<bigint, number>();
  const latencies: number[] = [], sendTimes: number[] = [];
  let frames = 0, bytes = 0, answeredUpTo = 0n, start = 0, camera: Camera | undefined;
  let attached!: () => void;
  const attach = new Promise<void>((resolve) => { attached = resolve; });

  const watching = (async () => {
    try {
      for await (const m of sessions.watchSession({ sessionId }, { signal: abort.signal })) {
        const now = performance.now();
        if (m.kind.case === "state") {
          camera ??= m.kind.value.scene?.camera;
          attached();
        } else if (m.kind.case === "frame") {
          const frame = m.kind.value;
          if (start) { frames += 1; bytes += frame.image.value?.byteLength ?? 0; }
          for (let seq = answeredUpTo + 1n; seq <= frame.lastEventSeq; ++seq) {
            const at = sentAt.get(seq);
            if (at !== undefined) latencies.push(now - at);
          }
          if (frame.lastEventSeq > answeredUpTo) answeredUpTo = frame.lastEventSeq;
        }
      }
    } catch (e) {
      if (!abort.signal.aborted) throw e;
    }
  })();
  await attach;
  if (!camera?.eye || !camera.target) throw new Error(`${path}: the session's state has no camera`);

  const events = Math.round(seconds * rate), step = (2 * Math.PI) / events;
  start = performance.now();
  for (let i = 1; i <= events; ++i) {
    const due = start + (i * 1000) / rate;
    await new Promise((r) => setTimeout(r, Math.max(0, due - performance.now())));
    const seq = BigInt(i), sent = performance.now();
    sentAt.set(seq, sent);
    const event = create(SessionEventSchema, { seq, kind: { case: "camera", value: orbited(camera, i * step) } });
    await sessions.sendEvents({ sessionId, events: [event] });
    sendTimes.push(performance.now() - sent);
  }
  const elapsed = (performance.now() - start) / 1000;
  for (const deadline = performance.now() + 2000; answeredUpTo < BigInt(events) && performance.now() < deadline;) {
    await new Promise((r) => setTimeout(r, 20));
  }
  abort.abort();
  await watching;
  await sessions.closeSession({ sessionId }).catch(() => {});
  latencies.sort((a, b) => a - b);
  sendTimes.sort((a, b) => a - b);
  return { path, device: created.device, events, answered: latencies.length, p50: percentile(latencies, 0.5), p95: percentile(latencies, 0.95),
           max: latencies[latencies.length - 1] ?? NaN, sendP50: percentile(sendTimes, 0.5), fps: frames / elapsed,
           mbps: bytes / elapsed / 1e6 };
}

const direct = createClient(SessionService, createGrpcTransport({ baseUrl: `http://${o.server}` }));
const gateway = createClient(SessionService,
  createGrpcWebTransport({ baseUrl: `http://${o.gateway}`, httpVersion: "1.1", useBinaryFormat: true }));
const results = [await measure("server (gRPC)", direct), await measure("cinevol-web (gRPC-web)", gateway)];
const f = (x: number) => x.toFixed(1);
for (const r of results) {
  console.log(`${r.path} on ${r.device}: ${r.answered}/${r.events} events answered, motion-to-photon p50/p95/max ` +
              `${f(r.p50)}/${f(r.p95)}/${f(r.max)} ms, SendEvents p50 ${f(r.sendP50)} ms, ${f(r.fps)} frames/s, ` +
              `${f(r.mbps)} MB/s`);
}
console.log(`gateway's added latency (p50): ${f(results[1].p50 - results[0].p50)} ms`);
console.log(JSON.stringify({ results, gatewayAddedP50Ms: results[1].p50 - results[0].p50 }));
if (results.some((r) => r.answered < r.events * 0.9)) {
  console.error("fewer than 9 in 10 events were answered");
  process.exit(1);
}

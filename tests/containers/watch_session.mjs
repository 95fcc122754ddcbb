// A session watched through cinevol-web from outside the stack, as a script speaks to it: the
// Connect protocol (docs/web.md) over HTTPS on loopback, the gateway's certificate checked
// against the stack's own. CreateSession, then WatchSession until the first frame (written to
// --out), or with --until-end until the stream ends (a drain), printing how it ended.
// No packages: node's https and the Connect framing (a flags byte, a length, a JSON message).
//
//   node watch_session.mjs --url https://127.0.0.1:PORT --ca tls.crt --token T --volume phantom:head \
//     --out frame.jpg [--until-end] [--timeout 60]
import { readFileSync, writeFileSync } from "node:fs";
import https from "node:https";
import { parseArgs } from "node:util";

const { values: args } = parseArgs({ options: {
  url: { type: "string" }, ca: { type: "string" }, token: { type: "string" }, volume: { type: "string" },
  out: { type: "string" }, "until-end": { type: "boolean", default: false }, timeout: { type: "string", default: "60" },
  width: { type: "string", default: "256" }, height: { type: "string", default: "256" },
} });
for (const k of ["url", "ca", "token", "volume"]) if (!args[k]) throw new Error(`--${k} is required`);
const base = new URL(args.url);
if (base.protocol !== "https:" || !["127.0.0.1", "localhost", "[::1]"].includes(base.hostname)) {
  throw new Error(`--url must be https on loopback, not ${args.url}`);
}
const ca = readFileSync(args.ca);
const deadline = Date.now() + Number(args.timeout) * 1000;
const started = Date.now();
const MAX_MESSAGE = 64 << 20;  // a frame of 256 x 256 is far below; a hostile answer stops here

function post(path, contentType, body) {
  return new Promise((resolve, reject) => {
    const request = https.request(new URL(path, base), {
      method: "POST", ca, timeout: Math.max(1, deadline - Date.now()),
      headers: { "content-type": contentType, "connect-protocol-version": "1", authorization: `Bearer ${args.token}` },
    }, resolve);
    request.on("timeout", () => request.destroy(new Error(`no answer from ${path} in time`)));
    request.on("error", reject);
    request.end(body);
  });
}

async function unary(method, message) {
  const answer = await post(`/cinevol.v1.SessionService/${method}`, "application/json", JSON.stringify(message));
  let text = "";
  for await (const chunk of answer) {
    text += chunk;
    if (text.length > MAX_MESSAGE) throw new Error(`${method}: answer too long`);
  }
  if (answer.statusCode !== 200) throw new Error(`${method}: HTTP ${answer.statusCode}: ${text.slice(0, 500)}`);
  return JSON.parse(text);
}

function envelope(message) {
  const json = Buffer.from(JSON.stringify(message));
  const head = Buffer.alloc(5);
  head.writeUInt32BE(json.length, 1);
  return Buffer.concat([head, json]);
}

/** The stream's messages, one at a time: { end: false, message } or { end: true, message: the end-stream JSON }. */
async function* messages(response) {
  let pending = Buffer.alloc(0);
  for await (const chunk of response) {
    pending = Buffer.concat([pending, chunk]);
    while (pending.length >= 5) {
      const flags = pending[0], length = pending.readUInt32BE(1);
      if (length > MAX_MESSAGE) throw new Error(`a message of ${length} bytes`);
      if (pending.length < 5 + length) break;
      const message = JSON.parse(pending.subarray(5, 5 + length).toString("utf8"));
      pending = pending.subarray(5 + length);
      yield { end: (flags & 2) !== 0, message };
    }
  }
}

const created = await unary("CreateSession", {
  volumeId: args.volume, viewport: { width: Number(args.width), height: Number(args.height) },
});
const session = created.sessionId;
console.log(`session ${session} on ${created.device} after ${Date.now() - started} ms`);
const watch = await post("/cinevol.v1.SessionService/WatchSession", "application/connect+json", envelope({ sessionId: session }));
if (watch.statusCode !== 200) throw new Error(`WatchSession: HTTP ${watch.statusCode}`);
const timer = setTimeout(() => watch.destroy(new Error(`no ${args["until-end"] ? "end" : "frame"} in ${args.timeout} s`)),
                         Math.max(1, deadline - Date.now()));
let frames = 0, ended = false;
for await (const { end, message } of messages(watch)) {
  if (end) {
    console.log(`stream ended after ${frames} frame(s): ${JSON.stringify(message)}`);
    ended = true;
    break;
  }
  if (message.notice) console.log(`notice: ${JSON.stringify(message.notice)}`);
  const frame = message.frame;
  if (!frame) continue;
  if (++frames === 1) {
    const image = Buffer.from(frame.jpeg ?? frame.png ?? "", "base64");
    const isJpeg = image[0] === 0xff && image[1] === 0xd8, isPng = image.subarray(1, 4).toString() === "PNG";
    if (!isJpeg && !isPng) throw new Error("the first frame is neither a JPEG nor a PNG");
    if (args.out) writeFileSync(args.out, image);
    console.log(`first frame ${frame.width}x${frame.height} (${image.length} bytes) ${Date.now() - started} ms after ` +
                "CreateSession was sent");
    if (!args["until-end"]) break;
    console.log("READY");  // the caller may now stop the server: the drain ends this stream
  }
}
clearTimeout(timer);
watch.destroy();
if (!args["until-end"]) {
  await unary("CloseSession", { sessionId: session }).catch((e) => console.log(`CloseSession: ${e.message}`));
} else if (frames === 0) {
  throw new Error("the stream ended before a frame");
} else if (!ended) {
  throw new Error(`the stream was cut after ${frames} frame(s), with no end message`);
}

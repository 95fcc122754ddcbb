// cinevol-web under a loopback attacker (issue 54): idle connections from one
// address leave room for everyone else, over HTTP/1.1 and over TLS with HTTP/2;
// connections that say nothing, or nothing more, are closed after the header
// and idle timeouts while a long stream lives on; requests for another host,
// from another origin, or with two Authorization headers are refused. A real
// cinevol-server (CPU) and cinevol-web on free loopback ports.
// Run directly (node gateway_holds.test.mjs) with CINEVOL_SERVER and CINEVOL_WEB set.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, readFileSync } from "node:fs";
import http from "node:http";
import http2 from "node:http2";
import net from "node:net";
import { join } from "node:path";
import { after, before, test } from "node:test";
import tls from "node:tls";
import { scratch, startWithPortFile, stop, type Running } from "./processes.js";

function required(name: string): string {
  const path = process.env[name];
  if (!path || !existsSync(path)) throw new Error(`${name} must name the built program (it is '${path ?? ""}')`);
  return path;
}
const SERVER = required("CINEVOL_SERVER"), WEB = required("CINEVOL_WEB");

// The gateway's defaults, which the attack meets.
const MAX_CONNECTIONS = 256, PER_ADDRESS = 32;
// The short timeouts the quick gateways are given, in seconds.
const HEADERS_S = 1, IDLE_S = 2, HANDSHAKE_S = 1;
// What a loaded machine may add to a timer before the close is seen, in seconds.
const SLACK_S = 3;
const ATTACKER = "127.0.0.2";

const cert = join(scratch, "cert.pem"), key = join(scratch, "key.pem");
let server: Running | undefined;
// Plain and TLS gateways with the default timeouts (the attacker's sockets stay), and with short ones.
const gateways: Record<"plain" | "tls" | "plainQuick" | "tlsQuick", Running | undefined> =
  { plain: undefined, tls: undefined, plainQuick: undefined, tlsQuick: undefined };
const port = (name: keyof typeof gateways) => gateways[name]!.port;
const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

before(async () => {
  execFileSync("openssl", ["req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
    "-days", "2", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
    "-keyout", key, "-out", cert], { stdio: "ignore" });
  server = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu"], "server");
  const base = ["--listen", "127.0.0.1:0", "--server", `127.0.0.1:${server.port}`];
  const withTls = ["--tls-cert", cert, "--tls-key", key];
  const quick = ["--headers-timeout", `${HEADERS_S}`, "--idle-timeout", `${IDLE_S}`,
                 "--tls-handshake-timeout", `${HANDSHAKE_S}`];
  [gateways.plain, gateways.tls, gateways.plainQuick, gateways.tlsQuick] = await Promise.all([
    startWithPortFile(WEB, base, "plain"), startWithPortFile(WEB, [...base, ...withTls], "tls"),
    startWithPortFile(WEB, [...base, ...quick], "plain-quick"),
    startWithPortFile(WEB, [...base, ...withTls, ...quick], "tls-quick")]);
});

after(async () => {
  // Short waits: stop() keeps its timer for them after the exit.
  await Promise.all(Object.values(gateways).map((g) => stop(g, "SIGTERM", 1)));
  await stop(server, "SIGTERM", 3);
});

interface Answer {
  status: number;
  body: string;
}

/** An HTTP/1.1 call to the plain gateway from 127.0.0.1, on a connection of its own. */
function http1Call(gatewayPort: number, path: string, headers: http.OutgoingHttpHeaders = {}, body = "{}"): Promise<Answer> {
  return new Promise((resolve, reject) => {
    const call = http.request({ host: "127.0.0.1", port: gatewayPort, path, method: "POST", agent: false, timeout: 20_000,
                                headers: { "content-type": "application/json", ...headers } }, (res) => {
      let text = "";
      res.on("data", (d) => { text += d; });
      res.on("end", () => resolve({ status: res.statusCode!, body: text }));
    });
    call.on("timeout", () => call.destroy(new Error(`no answer to ${path}`)));
    call.on("error", reject);
    call.end(body);
  });
}

function h2Connect(gatewayPort: number): http2.ClientHttp2Session {
  const session = http2.connect(`https://127.0.0.1:${gatewayPort}`, { ca: readFileSync(cert) });
  session.on("error", () => {});  // a session the gateway closes; each test looks at what it wanted
  return session;
}

/** An HTTP/2 call (TLS) on a session of its own. */
async function h2Call(gatewayPort: number, headers: http2.OutgoingHttpHeaders, body = "{}"): Promise<Answer> {
  const session = h2Connect(gatewayPort);
  try {
    return await new Promise<Answer>((resolve, reject) => {
      const stream = session.request({ ":method": "POST", "content-type": "application/json", ...headers });
      let status = 0, text = "";
      stream.setTimeout(20_000, () => stream.destroy(new Error(`no answer to ${headers[":path"]}`)));
      stream.on("response", (h) => { status = Number(h[":status"]); });
      stream.on("data", (d) => { text += d; });
      stream.on("end", () => resolve({ status, body: text }));
      stream.on("error", reject);
      stream.end(body);
    });
  } finally {
    session.close();
  }
}

const STATUS = "/cinevol.v1.ServerService/GetStatus";

/** The server's status answered through the gateway: a real call, not just the gateway's page. */
function assertStatusAnswer(answer: Answer): void {
  assert.equal(answer.status, 200, answer.body);
  assert.ok((JSON.parse(answer.body).presets as string[]).length > 0, answer.body);
}

/** `count` TCP connections from the attacker's address that say nothing; each settled: open, or closed by the gateway. */
async function idleConnections(gatewayPort: number, count: number) {
  const sockets: net.Socket[] = [];
  await Promise.all(Array.from({ length: count }, () => new Promise<void>((settled) => {
    const socket = net.connect({ host: "127.0.0.1", port: gatewayPort, localAddress: ATTACKER });
    sockets.push(socket);
    socket.on("error", () => {}).resume();
    socket.once("connect", settled);
    socket.once("close", settled);
  })));
  const open = () => sockets.filter((s) => !s.closed).length;
  // Those past the address's share are closed at once: wait (bounded) for it.
  for (const end = Date.now() + 5000; open() > PER_ADDRESS && Date.now() < end;) await sleep(50);
  await sleep(300);
  return { open, closeAll: () => sockets.forEach((s) => s.destroy()) };
}

test("idle connections from one address, more than --max-connections, leave HTTP/1.1 callers served", async () => {
  const attack = await idleConnections(port("plain"), MAX_CONNECTIONS + 44);
  try {
    assert.equal(attack.open(), PER_ADDRESS, "the attacker's address holds its share, the rest closed at once");
    assertStatusAnswer(await http1Call(port("plain"), STATUS));
    assert.equal(attack.open(), PER_ADDRESS, "the attacker's connections were still held during the call");
  } finally {
    attack.closeAll();
  }
});

test("idle connections from one address, more than --max-connections, leave HTTP/2 callers over TLS served", async () => {
  const attack = await idleConnections(port("tls"), MAX_CONNECTIONS + 44);
  try {
    assert.equal(attack.open(), PER_ADDRESS);
    assertStatusAnswer(await h2Call(port("tls"), { ":path": STATUS }));
    assert.equal(attack.open(), PER_ADDRESS);
  } finally {
    attack.closeAll();
  }
});

/**
 * Waits for the gateway to close `socket`, which must come `atLeastS` after now (its
 * timer's, not a refusal) and no later than SLACK_S after that. Call it as the timer starts.
 */
function closesAfter(socket: net.Socket | http2.ClientHttp2Session, atLeastS: number, what: string): Promise<void> {
  const start = performance.now();
  if (socket instanceof net.Socket) socket.resume();  // read on: an end nobody reads never closes
  return new Promise((resolve, reject) => {
    const late = setTimeout(() => {
      socket.destroy();
      reject(new Error(`${what}: still open after ${atLeastS + SLACK_S} s`));
    }, (atLeastS + SLACK_S) * 1000);
    socket.once("close", () => {
      clearTimeout(late);
      const seconds = (performance.now() - start) / 1000;
      if (seconds >= atLeastS - 0.3) resolve();
      else reject(new Error(`${what}: closed after ${seconds.toFixed(2)} s, before its timeout (${atLeastS} s)`));
    });
  });
}

function tlsConnect(gatewayPort: number, alpn: string): Promise<tls.TLSSocket> {
  return new Promise((resolve, reject) => {
    const socket = tls.connect({ host: "127.0.0.1", port: gatewayPort, ca: readFileSync(cert), ALPNProtocols: [alpn] },
                               () => resolve(socket));
    socket.on("error", reject);
  });
}

// HTTP/2 frames by hand, for what node's client will not send: a preface alone, two Authorization headers.
const PREFACE = Buffer.from("PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n");
function frame(type: number, flags: number, stream: number, payload: Buffer): Buffer {
  const header = Buffer.alloc(9);
  header.writeUIntBE(payload.length, 0, 3);
  header.writeUInt8(type, 3);
  header.writeUInt8(flags, 4);
  header.writeUInt32BE(stream, 5);
  return Buffer.concat([header, payload]);
}
const SETTINGS = frame(4, 0, 0, Buffer.alloc(0));
/** HPACK: a literal field without indexing, a new name, no Huffman (names and values under 127 bytes). */
function literal(name: string, value: string): Buffer {
  return Buffer.concat([Buffer.from([0, name.length]), Buffer.from(name), Buffer.from([value.length]), Buffer.from(value)]);
}

/** Sends one request's HEADERS (END_STREAM) on stream 1 and reads its DATA until the stream ends. */
async function rawH2Request(gatewayPort: number, fields: [string, string][]): Promise<string> {
  const socket = await tlsConnect(gatewayPort, "h2");
  const block = Buffer.concat(fields.map(([name, value]) => literal(name, value)));
  socket.write(Buffer.concat([PREFACE, SETTINGS, frame(1, 0x5, 1, block)]));
  let pending = Buffer.alloc(0), body = "";
  return new Promise((resolve, reject) => {
    const done = (error?: Error) => {
      socket.destroy();
      if (error) reject(error);
      else resolve(body);
    };
    socket.setTimeout(20_000, () => done(new Error("no answer over raw HTTP/2")));
    socket.on("close", () => done(new Error(`the connection closed; the answer so far: '${body}'`)));
    socket.on("data", (data: Buffer) => {
      pending = Buffer.concat([pending, data]);
      while (pending.length >= 9 && pending.length >= 9 + pending.readUIntBE(0, 3)) {
        const length = pending.readUIntBE(0, 3), type = pending[3], flags = pending[4];
        const stream = pending.readUInt32BE(5) & 0x7fffffff;
        if (stream === 1 && type === 0) body += pending.subarray(9, 9 + length).toString();
        if (stream === 1 && (type === 0 || type === 1) && flags & 0x1) return done();
        if (stream === 1 && type === 3) return done(new Error(`the stream was reset; the answer so far: '${body}'`));
        pending = pending.subarray(9 + length);
      }
    });
  });
}

test("the timeouts: a TLS handshake never finished, HTTP/1.1 headers never sent, an HTTP/2 preface alone", async () => {
  const silentTcp = net.connect({ host: "127.0.0.1", port: port("plainQuick") });
  const silentTls = net.connect({ host: "127.0.0.1", port: port("tlsQuick") });
  // Half a request's headers, then nothing.
  const halfHeaders = net.connect({ host: "127.0.0.1", port: port("plainQuick") },
                                  () => halfHeaders.write("GET / HTTP/1.1\r\nHost: 127"));
  const closed = [closesAfter(silentTcp, HEADERS_S, "a plain connection that says nothing"),
                  closesAfter(halfHeaders, HEADERS_S, "HTTP/1.1 headers never finished"),
                  closesAfter(silentTls, HANDSHAKE_S, "a TLS handshake never begun")];
  const prefaceOnly = await tlsConnect(port("tlsQuick"), "h2");
  assert.equal(prefaceOnly.alpnProtocol, "h2");
  prefaceOnly.write(Buffer.concat([PREFACE, SETTINGS]));
  closed.push(closesAfter(prefaceOnly, HEADERS_S, "an HTTP/2 session that sent only its preface"));
  await Promise.all(closed);
});

/** An HTTP/1.1 keep-alive exchange on `socket`; resolves with the answer once its body ("ok", chunked or not) has come. */
function keepAliveExchange(socket: net.Socket): Promise<string> {
  return new Promise((resolve, reject) => {
    let text = "";
    const late = setTimeout(() => reject(new Error(`no whole answer to GET /healthz: '${text}'`)), 20_000);
    socket.on("data", (d) => {
      text += d;
      if (/\r\n\r\n(3\r\n)?ok\n(\r\n0\r\n\r\n)?$/.test(text)) {
        clearTimeout(late);
        resolve(text);
      }
    });
    socket.write("GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: keep-alive\r\n\r\n");
  });
}

test("idle connections are closed after the idle timeout: HTTP/1.1 keep-alive, plain and over TLS, and HTTP/2", async () => {
  const http1Idle = async (socket: net.Socket, what: string) => {
    const answer = await keepAliveExchange(socket);
    const closed = closesAfter(socket, IDLE_S, what);
    assert.match(answer, /^HTTP\/1\.1 200 /);
    assert.match(answer, new RegExp(`keep-alive: timeout=${IDLE_S}`, "i"), `${what}: clients are told the idle timeout`);
    await closed;
  };
  const http2Idle = async () => {
    const session = h2Connect(port("tlsQuick"));
    const status = await new Promise<number>((resolve) => {
      session.request({ ":path": "/healthz" }).on("response", (h) => resolve(Number(h[":status"]))).resume();
    });
    const closed = closesAfter(session, IDLE_S, "an idle HTTP/2 session");
    assert.equal(status, 200);
    await closed;
  };
  await Promise.all([
    http1Idle(net.connect({ host: "127.0.0.1", port: port("plainQuick") }), "an idle HTTP/1.1 keep-alive connection"),
    tlsConnect(port("tlsQuick"), "http/1.1").then((s) => http1Idle(s, "an idle HTTP/1.1 keep-alive connection over TLS")),
    http2Idle(),
  ]);
});

/** Connect's envelope: a flags byte, a 32-bit length, the message. */
function envelope(message: object): Buffer {
  const json = Buffer.from(JSON.stringify(message));
  const head = Buffer.alloc(5);
  head.writeUInt32BE(json.length, 1);
  return Buffer.concat([head, json]);
}

const WATCH = { ":path": "/cinevol.v1.SessionService/WatchSession", "content-type": "application/connect+json" };

async function newSession(): Promise<string> {
  const answer = await http1Call(port("plainQuick"), "/cinevol.v1.SessionService/CreateSession",
                                 {}, JSON.stringify({ volumeId: "phantom:head", viewport: { width: 64, height: 64 } }));
  assert.equal(answer.status, 200, answer.body);
  return JSON.parse(answer.body).sessionId as string;
}

/** The end of what a stream sent, for a failure's message: the server says why it ended in words. */
const tail = (received: Buffer[]) => Buffer.concat(received).subarray(-300).toString().replace(/[^\x20-\x7e]/g, ".");

/** Watches over HTTP/1.1 for `seconds`; resolves with the bytes received, or fails when the stream ends before. */
function watchHttp1(sessionId: string, seconds: number): Promise<number> {
  return new Promise((resolve, reject) => {
    const received: Buffer[] = [];
    const call = http.request({ host: "127.0.0.1", port: port("plainQuick"), path: WATCH[":path"], method: "POST",
                                agent: false, headers: { "content-type": WATCH["content-type"] } }, (res) => {
      res.on("data", (d: Buffer) => received.push(d));
      res.on("error", () => {});
      res.on("close", () => reject(new Error(`the watch over HTTP/1.1 ended: '${tail(received)}'`)));
    });
    call.on("error", reject);
    call.end(envelope({ sessionId }));
    setTimeout(() => {
      resolve(Buffer.concat(received).length);  // first: the close that follows is ours
      call.destroy();
    }, seconds * 1000);
  });
}

/** Watches over HTTP/2 for `seconds`, as watchHttp1. */
function watchHttp2(sessionId: string, seconds: number): Promise<number> {
  const session = h2Connect(port("tlsQuick"));
  return new Promise((resolve, reject) => {
    const received: Buffer[] = [];
    const stream = session.request({ ":method": "POST", ...WATCH });
    stream.on("data", (d: Buffer) => received.push(d));
    stream.on("close", () => reject(new Error(`the watch over HTTP/2 ended: '${tail(received)}'`)));
    stream.end(envelope({ sessionId }));
    setTimeout(() => {
      resolve(Buffer.concat(received).length);  // first: the close that follows is ours
      session.destroy();
    }, seconds * 1000);
  });
}

test("a long WatchSession stream is not cut by the idle timeout, over HTTP/1.1 and HTTP/2", async () => {
  // A session each: a second watch of one session takes it over from the first.
  const [forHttp1, forHttp2] = await Promise.all([newSession(), newSession()]);
  const lasting = IDLE_S + HEADERS_S + 1;
  const [overHttp1, overHttp2] = await Promise.all([watchHttp1(forHttp1, lasting), watchHttp2(forHttp2, lasting)]);
  assert.ok(overHttp1 > 0 && overHttp2 > 0, `frames came (${overHttp1} and ${overHttp2} bytes)`);
});

test("another host, another origin and two Authorization headers are refused before any routing: HTTP/1.1", async () => {
  const gateway = port("plain");
  const rebound = await http1Call(gateway, STATUS, { host: `rebound.evil.example:${gateway}` });
  assert.equal(rebound.status, 421);
  assert.match(rebound.body, /does not answer for the host/);
  const foreign = await http1Call(gateway, STATUS, { origin: `http://rebound.evil.example:${gateway}` });
  assert.equal(foreign.status, 403);
  assert.match(foreign.body, /Origin is another site/);
  assertStatusAnswer(await http1Call(gateway, STATUS, { origin: `http://127.0.0.1:${gateway}` }));
  const two = await http1Call(gateway, STATUS, { Authorization: ["Bearer a", "Bearer b"] });  // two header lines
  assert.equal(two.status, 400);
  assert.match(two.body, /more than one Authorization/);
});

test("another host, another origin and two Authorization headers are refused before any routing: HTTP/2", async () => {
  const gateway = port("tls");
  const rebound = await h2Call(gateway, { ":path": STATUS, ":authority": `rebound.evil.example:${gateway}` });
  assert.equal(rebound.status, 421);
  const foreign = await h2Call(gateway, { ":path": STATUS, origin: `https://rebound.evil.example:${gateway}` });
  assert.equal(foreign.status, 403);
  assertStatusAnswer(await h2Call(gateway, { ":path": STATUS, origin: `https://127.0.0.1:${gateway}` }));
  const fields: [string, string][] = [[":method", "GET"], [":scheme", "https"], [":path", "/"],
                                      [":authority", `127.0.0.1:${gateway}`]];
  assert.match(await rawH2Request(gateway, fields), /<html|<!doctype/i, "the same request with one header is answered");
  const two = await rawH2Request(gateway, [...fields, ["authorization", "Bearer a"], ["authorization", "Bearer b"]]);
  assert.match(two, /more than one Authorization/);
});

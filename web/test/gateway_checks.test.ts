// cinevol-web's front door: which requests it answers (its own host names and
// origin, one Authorization) and how connections are counted and timed.
import assert from "node:assert/strict";
import { test } from "node:test";
import { addressKey, AddressCounts, IdleTimer } from "../gateway/connections.js";
import { isOwnOrigin, refuse, RequestChecks, type CheckedRequest } from "../gateway/request_checks.js";

const checks = new RequestChecks("gw.internal", ["viewer.example.org"]);
const http1 = (headers: Record<string, string | string[]>, method = "POST", url = "/cinevol.v1.ServerService/GetStatus") => {
  const rawHeaders = Object.entries(headers).flatMap(([name, v]) => (Array.isArray(v) ? v : [v]).flatMap((x) => [name, x]));
  return { rawHeaders, method, url } satisfies CheckedRequest;
};
const status = (req: CheckedRequest) => checks.refusal(req)?.status;

test("the gateway answers its own names only: --listen's host, loopback's, --allowed-hosts; any port", () => {
  for (const host of ["127.0.0.1:8080", "localhost", "LocalHost:1", "[::1]:8080", "[::1]", "gw.internal:8443",
                      "viewer.example.org"]) {
    assert.equal(status(http1({ Host: host })), undefined, host);
  }
  for (const host of ["evil.example", "127.0.0.1.evil.example", "localhost.", "localhost.evil.example:8080",
                      "viewer.example.org.evil.example", "127.0.0.2", "[::2]:80", "a b", ""]) {
    assert.equal(status(http1({ Host: host })), 421, host);
  }
  assert.match(checks.refusal(http1({ Host: "evil.example" }))!.text,
               /does not answer for the host 'evil.example'.*--allowed-hosts/);
  assert.equal(status(http1({})), 400, "no host at all");
  assert.equal(status(http1({ Host: ["localhost", "evil.example"] })), 400, "two hosts, the first ours");
});

test("HTTP/2: the :authority is checked, and must agree with a Host beside it", () => {
  assert.equal(status(http1({ ":authority": "127.0.0.1:8443", ":method": "POST" })), undefined);
  assert.equal(status(http1({ ":authority": "rebound.evil.example:8443" })), 421);
  assert.equal(status(http1({ ":authority": "127.0.0.1:8443", host: "evil.example" })), 400);
});

test("/healthz answers any host (probes ask by the pod's address); nothing else does", () => {
  assert.equal(status(http1({ Host: "10.1.2.3:8443" }, "GET", "/healthz")), undefined);
  assert.equal(status(http1({ Host: "10.1.2.3:8443" }, "GET", "/")), 421);
  assert.equal(status(http1({ Host: "10.1.2.3:8443" }, "POST", "/healthz")), 421);
});

test("a second Authorization header is refused, in any case of its name", () => {
  assert.equal(status(http1({ Host: "localhost", authorization: "Bearer a" })), undefined);
  const two = checks.refusal(http1({ Host: "localhost", Authorization: "Bearer a", authorization: "Bearer b" }));
  assert.equal(two?.status, 400);
  assert.match(two!.text, /more than one Authorization/);
  assert.equal(status(http1({ Host: "localhost", authorization: ["Bearer a", "Bearer a"] })), 400, "even the same twice");
});

test("a browser's Origin must be the request's own host and port; none (not a browser) is allowed", () => {
  assert.ok(isOwnOrigin("http://127.0.0.1:8080", "127.0.0.1:8080"));
  assert.ok(isOwnOrigin("http://localhost", "localhost:80"));
  assert.ok(isOwnOrigin("https://viewer.example.org", "viewer.example.org"), "behind a TLS proxy, the default port");
  assert.ok(isOwnOrigin("http://[::1]:8080", "[::1]:8080"));
  for (const [origin, host] of [["http://evil.example", "localhost:8080"], ["http://localhost:9999", "localhost:8080"],
                                ["null", "localhost:8080"], ["file://", "localhost"], ["http://localhost", "localhost:8080"],
                                ["https://viewer.example.org", "viewer.example.org:8443"],
                                ["ftp://localhost:8080", "localhost:8080"]]) {
    assert.ok(!isOwnOrigin(origin, host), `${origin} calling ${host}`);
  }
  assert.equal(status(http1({ Host: "127.0.0.1:8080", Origin: "http://127.0.0.1:8080" })), undefined);
  assert.equal(status(http1({ Host: "127.0.0.1:8080" })), undefined, "no Origin: a script, not a page");
  const foreign = checks.refusal(http1({ Host: "127.0.0.1:8080", Origin: "http://rebound.evil.example:8080" }));
  assert.equal(foreign?.status, 403);
  assert.match(foreign!.text, /Origin is another site/);
  assert.equal(status(http1({ Host: "127.0.0.1:8080", Origin: ["http://127.0.0.1:8080", "http://evil.example"] })), 403);
  assert.equal(status(http1({ ":authority": "127.0.0.1:8443", origin: "https://127.0.0.1:8443" })), undefined, "HTTP/2");
});

test("a refusal is answered as plain text", () => {
  let answered: { status: number; headers: Record<string, string>; body: string } | undefined;
  refuse({ writeHead: (s, h) => { answered = { status: s, headers: h, body: "" }; }, end: (b) => { answered!.body = b; } },
         { status: 421, text: "no" });
  assert.deepEqual(answered, { status: 421, body: "no\n", headers: {
    "content-type": "text/plain; charset=utf-8", "x-content-type-options": "nosniff", "cache-control": "no-store" } });
});

test("connections are counted per IPv4 address and per IPv6 /64", () => {
  assert.equal(addressKey("127.0.0.2"), "127.0.0.2");
  assert.equal(addressKey("::ffff:10.0.0.1"), "10.0.0.1");
  assert.equal(addressKey("2001:db8:1:2:3:4:5:6"), "2001:db8:1:2::/64");
  assert.equal(addressKey("2001:db8:1:2::9"), "2001:db8:1:2::/64");
  assert.equal(addressKey("2001:0db8:0001:0002::"), "2001:db8:1:2::/64");
  assert.equal(addressKey("::1"), "0:0:0:0::/64");
  assert.equal(addressKey("fe80::1%eth0"), "fe80:0:0:0::/64");
  assert.notEqual(addressKey("2001:db8:1:3::1"), addressKey("2001:db8:1:2::1"));
});

test("an address holds at most its share; a place given back is free again; 0: no limit", () => {
  const counts = new AddressCounts(2);
  assert.ok(counts.take("a") && counts.take("a"));
  assert.ok(!counts.take("a"), "the third is refused");
  assert.ok(counts.take("b"), "another address is not");
  counts.give("a");
  assert.ok(counts.take("a"));
  assert.equal(counts.held("a"), 2);
  const unlimited = new AddressCounts(0);
  for (let i = 0; i < 1000; i++) assert.ok(unlimited.take("a"));
});

const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

test("an idle timer closes a connection with no request: at the header timeout, then after the last request", async () => {
  let closed = 0;
  new IdleTimer(() => closed++, 10_000, 20);
  await sleep(100);
  assert.equal(closed, 1, "no request within the header timeout");

  closed = 0;
  const busy = new IdleTimer(() => closed++, 40, 20);
  busy.requestStarted();
  busy.requestStarted();
  await sleep(150);
  busy.requestEnded();
  await sleep(150);
  assert.equal(closed, 0, "a request still open: never idle, however long it lasts");
  busy.requestEnded();
  await sleep(150);
  assert.equal(closed, 1, "idle once the last request ended");

  closed = 0;
  const stopped = new IdleTimer(() => closed++, 20, 20);
  stopped.requestStarted();
  stopped.stop();
  stopped.requestEnded();
  await sleep(100);
  assert.equal(closed, 0, "a closed connection is timed no more");
});

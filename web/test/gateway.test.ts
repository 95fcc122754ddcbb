import assert from "node:assert/strict";
import { mkdtempSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { test } from "node:test";
import { isSessionHost, SessionRoutes } from "../gateway/forward.js";
import { isLoopback, parseHostPort, parseOptions, parseSessionHost, UsageError } from "../gateway/options.js";
import { StaticFiles } from "../gateway/static_files.js";

test("listen addresses: HOST:PORT, IPv6 in brackets, the port in range", () => {
  assert.deepEqual(parseHostPort("127.0.0.1:0", "--listen"), { host: "127.0.0.1", port: 0 });
  assert.deepEqual(parseHostPort("[::1]:8080", "--listen"), { host: "::1", port: 8080 });
  assert.throws(() => parseHostPort("localhost", "--listen"), UsageError);
  assert.throws(() => parseHostPort("a:70000", "--listen"), UsageError);
  assert.ok(isLoopback("127.0.0.2") && isLoopback("::1") && !isLoopback("0.0.0.0"));
});

test("beyond loopback the gateway needs TLS; half a TLS pair is refused", () => {
  const base = ["--static", "/nonexistent"];
  assert.throws(() => parseOptions([...base, "--listen", "0.0.0.0:8080"]), /need TLS/);
  assert.throws(() => parseOptions([...base, "--tls-cert", "c.pem"]), /go together/);
  assert.throws(() => parseOptions([...base, "--max-connections", "0"]), /whole number >= 1/);
  assert.throws(() => parseOptions([...base, "--bogus"]));
  assert.equal(parseOptions(base).port, 8080);
});

test("only the page's own files are served: no path reaches the disk", (t) => {
  const dir = mkdtempSync(join(tmpdir(), "cinevol-web-test-"));
  t.after(() => rmSync(dir, { recursive: true, force: true }));
  writeFileSync(join(dir, "index.html"), "<p>page</p>");
  writeFileSync(join(dir, "app.js"), "1");
  writeFileSync(join(dir, "secret.key"), "no");
  const files = new StaticFiles(dir);
  const answer = (url: string, method = "GET") => {
    let status = 0, headers: Record<string, string | number> = {}, body: Buffer | string = "";
    files.serve({ url, method }, {
      writeHead: (s, h) => { status = s; headers = h; },
      end: (b) => { body = b; },
    });
    return { status, headers, body: String(body) };
  };
  assert.equal(answer("/?volume=x").body, "<p>page</p>");
  assert.match(String(answer("/").headers["content-security-policy"]), /connect-src 'self'/);
  assert.equal(answer("/app.js").status, 200);
  for (const url of ["/secret.key", "/../etc/passwd", "/%2e%2e/app.js", "//app.js"]) assert.equal(answer(url).status, 404, url);
  assert.equal(answer("/", "POST").status, 405);
  assert.equal(answer("/healthz").body, "ok\n");
});

test("a session's calls go to its own server only where --session-hosts allows the host", () => {
  const made: string[] = [];
  const fallback = {} as never;
  const pods = [{ suffix: "cinevol-server-pods.default.svc", port: 50051 }];
  const routes = new SessionRoutes(fallback, pods, (a) => { made.push(a); return { a } as never; });
  const ctx = (address?: string) => ({ requestHeader: new Headers(address ? { "cinevol-session-address": address } : {}) }) as never;
  assert.equal(routes.pick(ctx()), fallback);
  routes.pick(ctx("cinevol-server-1.cinevol-server-pods.default.svc:50051"));
  routes.pick(ctx("cinevol-server-1.cinevol-server-pods.default.svc:50051"));
  assert.deepEqual(made, ["cinevol-server-1.cinevol-server-pods.default.svc:50051"], "one transport per address");
  for (const bad of ["169.254.169.254:80", "evil.example.org:50051", "x.cinevol-server-pods.default.svc.evil.org:1",
                     "a b:1", "evilcinevol-server-pods.default.svc:50051",
                     "cinevol-server-1.cinevol-server-pods.default.svc:22"]) {
    assert.throws(() => routes.pick(ctx(bad)), /does not route/, bad);
  }
  assert.equal(new SessionRoutes(fallback, [], () => { throw new Error("no"); }).pick(ctx("anything:1")), fallback);
});

test("--session-hosts matches whole labels, and only the suffix's port (the server's unless it says another)", () => {
  const hosts = ["pods.svc", "other.svc:6000"].map((entry) => parseSessionHost(entry, 50051));
  assert.deepEqual(hosts, [{ suffix: "pods.svc", port: 50051 }, { suffix: "other.svc", port: 6000 }]);
  assert.deepEqual(parseSessionHost(".Pods.Svc", 1), { suffix: "pods.svc", port: 1 }, "a leading dot, any case");
  for (const allowed of ["a.pods.svc:50051", "pods.svc:50051", "A.B.PODS.SVC:50051", "x.other.svc:6000"]) {
    assert.ok(isSessionHost(allowed, hosts), allowed);
  }
  for (const refused of ["evilpods.svc:50051", "a.pods.svc:50052", "a.pods.svc.evil.org:50051", "x.other.svc:50051",
                         "a..pods.svc:50051", "pods.svc", "a.pods.svc:50051:1"]) {
    assert.ok(!isSessionHost(refused, hosts), refused);
  }
  for (const bad of ["a b", "pods.svc:0", "pods.svc:70000", "http://pods.svc", ""]) {
    assert.throws(() => parseSessionHost(bad, 50051), UsageError, bad);
  }
});

test("the connection limits and timeouts: documented defaults, whole numbers and seconds checked", () => {
  const base = ["--static", "/nonexistent"];
  const o = parseOptions(base);
  assert.equal(o.maxConnections, 256);
  assert.equal(o.maxConnectionsPerAddress, 32);
  assert.deepEqual(o.timeouts, { tlsHandshakeMs: 10_000, headersMs: 10_000, idleMs: 60_000 });
  assert.deepEqual(o.allowedHosts, []);
  const set = parseOptions([...base, "--max-connections-per-address", "0", "--idle-timeout", "0.5",
                            "--headers-timeout", "2", "--tls-handshake-timeout", "3"]);
  assert.equal(set.maxConnectionsPerAddress, 0, "0: no limit per address (behind a proxy)");
  assert.deepEqual(set.timeouts, { tlsHandshakeMs: 3000, headersMs: 2000, idleMs: 500 });
  for (const [flag, bad] of [["--max-connections-per-address", "-1"], ["--max-connections-per-address", "2.5"],
                             ["--idle-timeout", "0"], ["--headers-timeout", "x"], ["--tls-handshake-timeout", "1e9"]]) {
    assert.throws(() => parseOptions([...base, `${flag}=${bad}`]), UsageError, `${flag}=${bad}`);
  }
});

test("--allowed-hosts takes host names (any case, IPv6 in brackets or not), never a port", () => {
  const base = ["--static", "/nonexistent"];
  assert.deepEqual(parseOptions([...base, "--allowed-hosts", "Viewer.Example.org, [fd00::2],fd00::3"]).allowedHosts,
                   ["viewer.example.org", "[fd00::2]", "[fd00::3]"]);
  for (const bad of ["viewer.example.org:443", "http://viewer.example.org", "a b"]) {
    assert.throws(() => parseOptions([...base, "--allowed-hosts", bad]), /not a host name/, bad);
  }
});

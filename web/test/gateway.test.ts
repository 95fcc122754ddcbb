import assert from "node:assert/strict";
import { mkdtempSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { test } from "node:test";
import { isLoopback, parseHostPort, parseOptions, UsageError } from "../gateway/options.js";
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
  assert.throws(() => parseOptions([...base, "--max-connections", "0"]), /positive/);
  assert.throws(() => parseOptions([...base, "--bogus"]));
  assert.equal(parseOptions(base).port, 8080);
});

test("only the page's own files are served: no path reaches the disk", () => {
  const dir = mkdtempSync(join(tmpdir(), "cinevol-web-test-"));
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

test("a session's calls go to its own server only where --session-hosts allows the host", async () => {
  const { SessionRoutes } = await import("../gateway/forward.js");
  const made: string[] = [];
  const fallback = {} as never;
  const routes = new SessionRoutes(fallback, [".cinevol-server-pods.default.svc"], (a) => { made.push(a); return { a } as never; });
  const ctx = (address?: string) => ({ requestHeader: new Headers(address ? { "cinevol-session-address": address } : {}) }) as never;
  assert.equal(routes.pick(ctx()), fallback);
  routes.pick(ctx("cinevol-server-1.cinevol-server-pods.default.svc:50051"));
  routes.pick(ctx("cinevol-server-1.cinevol-server-pods.default.svc:50051"));
  assert.deepEqual(made, ["cinevol-server-1.cinevol-server-pods.default.svc:50051"], "one transport per address");
  for (const bad of ["169.254.169.254:80", "evil.example.org:50051", "x.cinevol-server-pods.default.svc.evil.org:1",
                     "a b:1"]) {
    assert.throws(() => routes.pick(ctx(bad)), /does not route/, bad);
  }
  assert.equal(new SessionRoutes(fallback, [], () => { throw new Error("no"); }).pick(ctx("anything:1")), fallback);
});

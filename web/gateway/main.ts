// cinevol-web: serves the browser page and translates gRPC-web and Connect
// to cinevol-server's gRPC over HTTP/2 (docs/web.md).
import { writeFileSync } from "node:fs";
import http from "node:http";
import http2 from "node:http2";
import type { AddressInfo } from "node:net";
import { connectNodeAdapter, createGrpcTransport } from "@connectrpc/connect-node";
import { PacsService, ServerService, SessionService, VolumeService } from "../gen/cinevol/v1/service_pb.js";
import { ConnectionGuard } from "./connections.js";
import { forwardService, SessionRoutes } from "./forward.js";
import { parseOptions, UsageError, USAGE, type GatewayOptions } from "./options.js";
import { answerRendered } from "./rendered.js";
import { RenderQueue } from "./render_queue.js";
import { refuse, RequestChecks } from "./request_checks.js";
import { answerSigning, SignedUrls } from "./signed_urls.js";
import { StaticFiles } from "./static_files.js";

// A batch of events with its transfer functions stays far below this; a
// frame (the largest message, a PNG final frame) comes the other way.
const MAX_REQUEST_BYTES = 4 << 20;

function serverTransport(o: GatewayOptions, address: string) {
  const tls = o.serverTls;
  return createGrpcTransport({
    baseUrl: `${tls ? "https" : "http"}://${address}`,
    nodeOptions: tls ? { ca: tls.ca, cert: tls.cert, key: tls.key, servername: tls.serverName } : undefined,
  });
}

function start(o: GatewayOptions): void {
  const files = new StaticFiles(o.staticDir);
  const server = serverTransport(o, o.server);
  const sessions = new SessionRoutes(server, o.sessionHosts, (address) => serverTransport(o, address));
  const translate = connectNodeAdapter({
    routes: (router) => {
      for (const service of [VolumeService, PacsService, ServerService]) forwardService(router, service, () => server);
      forwardService(router, SessionService, (ctx) => sessions.pick(ctx));
    },
    readMaxBytes: MAX_REQUEST_BYTES,
    fallback: (req, res) => files.serve(req, res),
  });
  const guard = new ConnectionGuard(o.maxConnectionsPerAddress, o.timeouts);
  const checks = new RequestChecks(o.host, o.allowedHosts);
  const signed = new SignedUrls();
  const queue = new RenderQueue();
  const handler = (req: http.IncomingMessage | http2.Http2ServerRequest,
                   res: http.ServerResponse | http2.Http2ServerResponse) => {
    guard.requestStarted(req, res);
    const refusal = checks.refusal(req);
    if (refusal) refuse(res, refusal);
    else if (!answerSigning(server, signed, req, res) && !answerRendered(server, req, res, queue, signed)) translate(req, res);
  };
  const listener = o.tls
    ? http2.createSecureServer({ cert: o.tls.cert, key: o.tls.key, allowHTTP1: true,
                                 handshakeTimeout: o.timeouts.tlsHandshakeMs,
                                 settings: { maxConcurrentStreams: 64 } }, handler)
    : http.createServer(handler);
  listener.maxConnections = o.maxConnections;
  // Node's own keep-alive timer (HTTP/1.1, plain or over TLS) agrees with the guard's and tells clients
  // (Keep-Alive: timeout=N); the HTTP/2 server has the property too, untyped.
  (listener as http.Server).keepAliveTimeout = o.timeouts.idleMs;
  guard.attach(listener, Boolean(o.tls));
  listener.on("error", (e: NodeJS.ErrnoException) => {
    console.error(`cinevol-web: cannot listen on ${o.host}:${o.port}: ${e.code ?? e.message}`);
    process.exit(1);
  });
  listener.listen(o.port, o.host, () => {
    const port = (listener.address() as AddressInfo).port;
    if (o.portFile) writeFileSync(o.portFile, `${port}\n`);
    const scheme = o.tls ? "https" : "http";
    console.log(`cinevol-web: serving ${scheme}://${o.host.includes(":") ? `[${o.host}]` : o.host}:${port}/ ` +
                `for cinevol-server at ${o.server}${o.serverTls ? " (TLS)" : ""}`);
  });
  for (const signal of ["SIGTERM", "SIGINT"] as const) {
    process.on(signal, () => {
      listener.close();
      process.exit(0);
    });
  }
}

try {
  start(parseOptions(process.argv.slice(2)));
} catch (e) {
  if (!(e instanceof UsageError)) throw e;
  if (e.message) console.error(`cinevol-web: ${e.message}`);
  console.error(USAGE);
  process.exit(e.message ? 2 : 0);
}

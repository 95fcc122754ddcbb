// cinevol-web's command line (a contract: scripts and checks use these names).
import { readFileSync } from "node:fs";
import { parseArgs } from "node:util";
import { canonicalHostName } from "./request_checks.js";

export interface GatewayOptions {
  host: string;
  port: number;
  portFile?: string;
  server: string;           // HOST:PORT of cinevol-server
  tls?: { cert: Buffer; key: Buffer };
  serverTls?: { ca?: Buffer; cert?: Buffer; key?: Buffer; serverName?: string };
  staticDir: string;
  maxConnections: number;
  maxConnectionsPerAddress: number;  // 0: no limit (behind a proxy every client has its address)
  timeouts: Timeouts;
  allowedHosts: string[];   // host names the gateway answers besides its own (RequestChecks)
  sessionHosts: SessionHost[];  // where a session's own server may be (SessionRoutes)
}

/** How long a connection may say nothing useful before it is closed (ConnectionGuard), in ms. */
export interface Timeouts {
  tlsHandshakeMs: number;  // from the TCP connection to a finished TLS handshake
  headersMs: number;       // from the connection (after TLS) to its first complete request or HTTP/2 stream
  idleMs: number;          // with no request or stream open, after the last one ended
}

/** A --session-hosts entry: hosts equal to `suffix` or ending in "." + suffix, on `port` only. */
export interface SessionHost {
  suffix: string;
  port: number;
}

export const USAGE = `usage: cinevol-web --listen HOST:PORT [--port-file F] --server ADDR
                   [--tls-cert F --tls-key F]
                   [--server-tls-ca F [--server-tls-cert F --server-tls-key F] [--server-tls-name N]]
                   [--session-hosts SUFFIX[:PORT][,...]] [--allowed-hosts NAME[,NAME...]]
                   [--max-connections N] [--max-connections-per-address N]
                   [--tls-handshake-timeout S] [--headers-timeout S] [--idle-timeout S]
Serves the cinevol page and translates gRPC-web and Connect to cinevol-server's gRPC.
Open http://HOST:PORT/?volume=ID#token=T. Defaults: --listen 127.0.0.1:8080, --server 127.0.0.1:50051.`;

/** An error in the command line: printed with the usage, exit code 2. */
export class UsageError extends Error {}

/** HOST:PORT, the host as given ("[::1]:80" for IPv6); the port in [0, 65535]. */
export function parseHostPort(text: string, flag: string): { host: string; port: number } {
  const m = /^(\[[^\]]+\]|[^:]+):(\d{1,5})$/.exec(text);
  const port = m ? Number(m[2]) : NaN;
  if (!m || port > 65535) throw new UsageError(`${flag}: '${text}' is not HOST:PORT`);
  return { host: m[1].replace(/^\[|\]$/g, ""), port };
}

export function isLoopback(host: string): boolean {
  return host === "localhost" || host === "::1" || /^127\.\d+\.\d+\.\d+$/.test(host);
}

function readFlagFile(path: string | undefined, flag: string): Buffer | undefined {
  if (path === undefined) return undefined;
  try {
    return readFileSync(path);
  } catch (e) {
    throw new UsageError(`${flag}: cannot read '${path}': ${(e as NodeJS.ErrnoException).code ?? e}`);
  }
}

export function parseOptions(argv: string[]): GatewayOptions {
  const { values } = parseArgs({
    args: argv,
    strict: true,
    options: {
      listen: { type: "string", default: "127.0.0.1:8080" },
      "port-file": { type: "string" },
      server: { type: "string", default: "127.0.0.1:50051" },
      "tls-cert": { type: "string" },
      "tls-key": { type: "string" },
      "server-tls-ca": { type: "string" },
      "server-tls-cert": { type: "string" },
      "server-tls-key": { type: "string" },
      "server-tls-name": { type: "string" },
      "max-connections": { type: "string", default: "256" },
      "max-connections-per-address": { type: "string", default: "32" },
      "tls-handshake-timeout": { type: "string", default: "10" },
      "headers-timeout": { type: "string", default: "10" },
      "idle-timeout": { type: "string", default: "60" },
      "allowed-hosts": { type: "string", default: "" },
      "session-hosts": { type: "string", default: "" },
      static: { type: "string" },
      help: { type: "boolean" },
    },
  });
  if (values.help) throw new UsageError("");
  const { host, port } = parseHostPort(values.listen!, "--listen");
  const server = parseHostPort(values.server!, "--server");
  if (!values.static) throw new UsageError("--static: the built page's folder is required (the cinevol-web script sets it)");
  if (Boolean(values["tls-cert"]) !== Boolean(values["tls-key"])) {
    throw new UsageError("--tls-cert and --tls-key go together");
  }
  if (Boolean(values["server-tls-cert"]) !== Boolean(values["server-tls-key"])) {
    throw new UsageError("--server-tls-cert and --server-tls-key go together");
  }
  // Browsers send their token through here: beyond loopback it travels only under TLS.
  if (!isLoopback(host) && !values["tls-cert"]) {
    throw new UsageError(`--listen ${values.listen}: beyond loopback the page and its tokens need TLS: ` +
                         "give --tls-cert and --tls-key");
  }
  const tls = values["tls-cert"]
    ? { cert: readFlagFile(values["tls-cert"], "--tls-cert")!, key: readFlagFile(values["tls-key"], "--tls-key")! }
    : undefined;
  const wantsServerTls = ["server-tls-ca", "server-tls-cert", "server-tls-name"].some((k) => values[k as "server-tls-ca"]);
  const serverTls = wantsServerTls
    ? {
        ca: readFlagFile(values["server-tls-ca"], "--server-tls-ca"),
        cert: readFlagFile(values["server-tls-cert"], "--server-tls-cert"),
        key: readFlagFile(values["server-tls-key"], "--server-tls-key"),
        serverName: values["server-tls-name"],
      }
    : undefined;
  return {
    host, port, portFile: values["port-file"], server: values.server!, tls, serverTls,
    staticDir: values.static,
    maxConnections: wholeNumber(values["max-connections"]!, "--max-connections", 1),
    maxConnectionsPerAddress: wholeNumber(values["max-connections-per-address"]!, "--max-connections-per-address", 0),
    timeouts: {
      tlsHandshakeMs: seconds(values["tls-handshake-timeout"]!, "--tls-handshake-timeout"),
      headersMs: seconds(values["headers-timeout"]!, "--headers-timeout"),
      idleMs: seconds(values["idle-timeout"]!, "--idle-timeout"),
    },
    allowedHosts: list(values["allowed-hosts"]!).map(allowedHost),
    sessionHosts: list(values["session-hosts"]!).map((entry) => parseSessionHost(entry, server.port)),
  };
}

function list(text: string): string[] {
  return text.split(",").map((item) => item.trim()).filter(Boolean);
}

function wholeNumber(text: string, flag: string, least: number): number {
  const n = Number(text);
  if (!Number.isInteger(n) || n < least) throw new UsageError(`${flag}: '${text}' is not a whole number >= ${least}`);
  return n;
}

// A day at most: node's timers take no more than 24.8 days, and fire at once beyond.
const MAX_SECONDS = 86400;

/** Seconds (fractions allowed, for tests) in (0, a day], as milliseconds. */
function seconds(text: string, flag: string): number {
  const s = Number(text);
  if (!(s > 0 && s <= MAX_SECONDS)) {
    throw new UsageError(`${flag}: '${text}' is not a number of seconds in (0, ${MAX_SECONDS}]`);
  }
  return Math.ceil(s * 1000);
}

function allowedHost(name: string): string {
  const canonical = canonicalHostName(name);
  if (!canonical) throw new UsageError(`--allowed-hosts: '${name}' is not a host name (give names without ports)`);
  return canonical;
}

/** SUFFIX or SUFFIX:PORT; a leading dot is allowed; the port defaults to --server's. */
export function parseSessionHost(entry: string, serverPort: number): SessionHost {
  const m = /^\.?((?:[a-z0-9-]+\.)*[a-z0-9-]+)(?::(\d{1,5}))?$/i.exec(entry);
  const port = m?.[2] === undefined ? serverPort : Number(m[2]);
  if (!m || port < 1 || port > 65535) throw new UsageError(`--session-hosts: '${entry}' is not SUFFIX or SUFFIX:PORT`);
  return { suffix: m[1].toLowerCase(), port };
}

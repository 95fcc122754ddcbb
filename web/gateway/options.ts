// cinevol-web's command line (a contract: scripts and checks use these names).
import { readFileSync } from "node:fs";
import { parseArgs } from "node:util";

export interface GatewayOptions {
  host: string;
  port: number;
  portFile?: string;
  server: string;           // HOST:PORT of cinevol-server
  tls?: { cert: Buffer; key: Buffer };
  serverTls?: { ca?: Buffer; cert?: Buffer; key?: Buffer; serverName?: string };
  staticDir: string;
  maxConnections: number;
  sessionHosts: string[];   // DNS suffixes a session's own server may have (SessionRoutes)
}

export const USAGE = `usage: cinevol-web --listen HOST:PORT [--port-file F] --server ADDR
                   [--tls-cert F --tls-key F]
                   [--server-tls-ca F [--server-tls-cert F --server-tls-key F] [--server-tls-name N]]
                   [--session-hosts SUFFIX[,SUFFIX...]] [--max-connections N]
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
      "session-hosts": { type: "string", default: "" },
      static: { type: "string" },
      help: { type: "boolean" },
    },
  });
  if (values.help) throw new UsageError("");
  const { host, port } = parseHostPort(values.listen!, "--listen");
  parseHostPort(values.server!, "--server");
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
  const maxConnections = Number(values["max-connections"]);
  if (!Number.isInteger(maxConnections) || maxConnections < 1) {
    throw new UsageError(`--max-connections: '${values["max-connections"]}' is not a positive whole number`);
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
    staticDir: values.static, maxConnections,
    sessionHosts: values["session-hosts"]!.split(",").map((h) => h.trim()).filter(Boolean),
  };
}

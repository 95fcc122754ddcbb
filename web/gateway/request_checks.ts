// Which requests cinevol-web answers at all, before any routing: those for its
// own host names (a page whose name was rebound to 127.0.0.1 gets nothing), from
// its own origin when a browser says one, with at most one Authorization header.

/** What a check reads of a node request (HTTP/1.1 or HTTP/2 alike): the headers as they came, duplicates kept. */
export interface CheckedRequest {
  rawHeaders: string[];  // name, value, name, value...; HTTP/2's pseudo-headers (":authority") too
  method?: string;
  url?: string;
}

export interface Refusal {
  status: number;
  text: string;
}

/** A host name as Host headers carry it: lower case, IPv6 in brackets; undefined when it is not one. */
export function canonicalHostName(name: string): string | undefined {
  const lower = name.toLowerCase();
  if (/^(?:[a-z0-9-]+\.)*[a-z0-9-]+$/.test(lower)) return lower;
  const v6 = /^\[?([0-9a-f:.]+)\]?$/.exec(lower);
  return v6 && v6[1].includes(":") ? `[${v6[1]}]` : undefined;
}

/** A Host or :authority value split into its host name (canonical) and port (absent: the scheme's own). */
export function parseHost(value: string): { name: string; port?: number } | undefined {
  const m = /^(\[[0-9a-f:.]+\]|[^:[\]]+)(?::(\d{1,5}))?$/i.exec(value);
  const name = m && canonicalHostName(m[1]);
  return name ? { name, port: m[2] === undefined ? undefined : Number(m[2]) } : undefined;
}

const DEFAULT_PORTS: Record<string, number> = { "http:": 80, "https:": 443 };

/**
 * Whether a browser's Origin is the request's own: same host and port as its Host
 * (which is one of ours). The scheme is not compared: a TLS-terminating proxy
 * may stand in front, and no other scheme can be served on the same host and port.
 */
export function isOwnOrigin(origin: string, host: string): boolean {
  let url: URL;
  try {
    url = new URL(origin);
  } catch {
    return false;  // "null" (a sandboxed frame, a file) among others
  }
  const defaultPort = DEFAULT_PORTS[url.protocol];
  const target = parseHost(host);
  if (defaultPort === undefined || !target) return false;
  return url.hostname === target.name && Number(url.port || defaultPort) === (target.port ?? defaultPort);
}

/** Every value of the named headers (lower-case names), in the order they came. */
export function headerValues(rawHeaders: string[], ...names: string[]): string[] {
  const values: string[] = [];
  for (let i = 0; i + 1 < rawHeaders.length; i += 2) {
    if (names.includes(rawHeaders[i].toLowerCase())) values.push(rawHeaders[i + 1]);
  }
  return values;
}

export class RequestChecks {
  private readonly names: Set<string>;

  /** The gateway's names: the --listen host, loopback's own names, and --allowed-hosts (canonical). */
  constructor(listenHost: string, allowedHosts: string[]) {
    const own = [listenHost, "localhost", "127.0.0.1", "::1"].map((h) => canonicalHostName(h)!);
    this.names = new Set([...own, ...allowedHosts]);
  }

  /** Why the request is not answered, or undefined when it may go on to routing. */
  refusal(req: CheckedRequest): Refusal | undefined {
    return this.hostRefusal(req) ?? authorizationRefusal(req) ?? originRefusal(req);
  }

  private hostRefusal(req: CheckedRequest): Refusal | undefined {
    // Probes (Kubernetes asks by the pod's address) learn only "ok" from it.
    if (req.url === "/healthz" && (req.method === "GET" || req.method === "HEAD")) return undefined;
    const hosts = headerValues(req.rawHeaders, "host", ":authority");
    if (hosts.length === 0) return { status: 400, text: "the request names no host (Host or :authority)" };
    if (new Set(hosts).size > 1) return { status: 400, text: "the request names two different hosts" };
    const name = parseHost(hosts[0])?.name;
    if (name && this.names.has(name)) return undefined;
    return { status: 421, text: `cinevol-web does not answer for the host '${hosts[0].slice(0, 200)}' ` +
                                "(an operator adds its names with --allowed-hosts)" };
  }
}

// The gateway forwards one token; node would keep the first of two and hide the second from the server.
function authorizationRefusal(req: CheckedRequest): Refusal | undefined {
  if (headerValues(req.rawHeaders, "authorization").length <= 1) return undefined;
  return { status: 400, text: "the request carries more than one Authorization header: send one" };
}

// Pages of other sites may not call the API (absent Origin: not a browser, or a same-origin GET).
function originRefusal(req: CheckedRequest): Refusal | undefined {
  const origins = headerValues(req.rawHeaders, "origin");
  if (origins.length === 0) return undefined;
  const host = headerValues(req.rawHeaders, "host", ":authority")[0] ?? "";
  if (origins.length === 1 && isOwnOrigin(origins[0], host)) return undefined;
  return { status: 403, text: "cinevol-web answers only its own page: the request's Origin is another site" };
}

/** What refuse() needs of a node response (HTTP/1.1 or HTTP/2 alike). */
interface Response {
  writeHead(status: number, headers: Record<string, string>): unknown;
  end(body: string): unknown;
}

/** Answers a refusal in plain words. */
export function refuse(res: Response, refusal: Refusal): void {
  res.writeHead(refusal.status, { "content-type": "text/plain; charset=utf-8", "x-content-type-options": "nosniff",
                                  "cache-control": "no-store" });
  res.end(refusal.text + "\n");
}

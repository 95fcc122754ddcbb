// Who may hold cinevol-web's connections, and for how long: a client address
// gets a share of them, and a connection with no request open is closed after
// a short while, whether it speaks HTTP/1.1 (plain or over TLS) or HTTP/2. A
// request or stream that is open (a WatchSession streams for minutes) is never
// cut here.
import type { IncomingMessage, Server as HttpServer } from "node:http";
import type { Http2SecureServer, Http2ServerRequest, ServerHttp2Session } from "node:http2";
import type { Socket } from "node:net";
import type { TLSSocket } from "node:tls";
import type { Timeouts } from "./options.js";

/** The address connections are counted by: IPv4 as is, IPv6 by its /64 (one host is usually given a whole /64). */
export function addressKey(address: string): string {
  const mapped = /^::ffff:(\d+\.\d+\.\d+\.\d+)$/i.exec(address);
  if (mapped) return mapped[1];
  if (!address.includes(":")) return address;  // IPv4, or "" for a socket already gone
  const [left, right] = address.split("%")[0].split("::").map((half) => (half ? half.split(":") : []));
  const zeros = right ? Array(Math.max(0, 8 - left.length - right.length)).fill("0") : [];
  const groups = [...left, ...zeros, ...(right ?? [])].slice(0, 4);
  return groups.map((g) => parseInt(g, 16).toString(16)).join(":") + "::/64";
}

/** Open connections counted per address; `limit` 0: no limit. */
export class AddressCounts {
  private readonly open = new Map<string, number>();

  constructor(private readonly limit: number) {}

  /** Takes a place for one more connection from `key`; false when it holds all it may. */
  take(key: string): boolean {
    const held = this.open.get(key) ?? 0;
    if (this.limit > 0 && held >= this.limit) return false;
    this.open.set(key, held + 1);
    return true;
  }

  give(key: string): void {
    const held = (this.open.get(key) ?? 1) - 1;
    if (held > 0) this.open.set(key, held);
    else this.open.delete(key);
  }

  held(key: string): number {
    return this.open.get(key) ?? 0;
  }
}

/**
 * Closes a connection (or HTTP/2 session) while it has no request open: `firstMs`
 * after it started unless a request came, `idleMs` after its last request ended.
 */
export class IdleTimer {
  private open = 0;
  private stopped = false;
  private timer: NodeJS.Timeout;

  constructor(private readonly close: () => void, private readonly idleMs: number, firstMs: number) {
    this.timer = this.arm(firstMs);
  }

  requestStarted(): void {
    if (this.open++ === 0) clearTimeout(this.timer);
  }

  requestEnded(): void {
    if (--this.open === 0 && !this.stopped) this.timer = this.arm(this.idleMs);
  }

  /** The connection closed: nothing more to time. */
  stop(): void {
    this.stopped = true;
    clearTimeout(this.timer);
  }

  private arm(ms: number): NodeJS.Timeout {
    return setTimeout(this.close, ms).unref();
  }
}

type Listener = HttpServer | Http2SecureServer;

export class ConnectionGuard {
  private readonly counts: AddressCounts;
  private readonly http1 = new WeakMap<Socket, IdleTimer>();

  constructor(perAddress: number, private readonly timeouts: Timeouts) {
    this.counts = new AddressCounts(perAddress);
  }

  /**
   * Watches every connection of `listener`. Over TLS the handshake's own timeout
   * is the server's `handshakeTimeout` option; the header timeout starts after it.
   */
  attach(listener: Listener, tls: boolean): void {
    listener.on("connection", (socket: Socket) => this.accepted(socket, tls));
    if (!tls) return;
    // HTTP/2's own listener has already made the session (below) when ALPN chose h2.
    listener.on("secureConnection", (socket: TLSSocket) => socket.alpnProtocol !== "h2" && this.http1Started(socket));
    listener.on("session", (session: ServerHttp2Session) => this.http2Started(session));
  }

  /** Every request the handler gets: an HTTP/1.1 connection is not idle until its answer has gone. */
  requestStarted(req: IncomingMessage | Http2ServerRequest, res: { once(event: "close", f: () => void): unknown }): void {
    if (req.httpVersionMajor >= 2) return;  // HTTP/2 counts its streams (http2Started)
    const timer = this.http1.get(req.socket as Socket);
    if (!timer) return;
    timer.requestStarted();
    res.once("close", () => timer.requestEnded());
  }

  // A TCP connection, before TLS or HTTP: past its address's share it is closed at once.
  private accepted(socket: Socket, tls: boolean): void {
    const key = addressKey(socket.remoteAddress ?? "");
    if (!this.counts.take(key)) {
      socket.destroy();
      return;
    }
    socket.once("close", () => this.counts.give(key));
    if (!tls) this.http1Started(socket);
  }

  private http1Started(socket: Socket): void {
    const timer = new IdleTimer(() => socket.destroy(), this.timeouts.idleMs, this.timeouts.headersMs);
    this.http1.set(socket, timer);
    socket.once("close", () => timer.stop());
  }

  // An HTTP/2 session's requests are its streams; a stream opens once its HEADERS are complete.
  private http2Started(session: ServerHttp2Session): void {
    const timer = new IdleTimer(() => session.close(), this.timeouts.idleMs, this.timeouts.headersMs);
    session.on("stream", (stream) => {
      timer.requestStarted();
      stream.once("close", () => timer.requestEnded());
    });
    session.once("close", () => timer.stop());
  }
}

// The translation: every unary and server-streaming method of cinevol's
// services, taken in gRPC-web or Connect from the browser and made as the
// same gRPC call to cinevol-server. The caller's `authorization` header goes
// through as it came; the gateway adds nothing to a session of its own.
// Client- and bidirectional-streaming methods (UploadVolume, StreamSession)
// are not offered: browsers cannot make them; they answer UNIMPLEMENTED.
import type { DescService } from "@bufbuild/protobuf";
import {
  Code, ConnectError, createClient, type CallOptions, type ConnectRouter, type HandlerContext, type Transport,
} from "@connectrpc/connect";
import type { SessionHost } from "./options.js";

/** The call to the server made on behalf of the browser's call: its token, deadline and cancellation. */
function passThrough(ctx: HandlerContext): CallOptions {
  const headers = new Headers();
  const authorization = ctx.requestHeader.get("authorization");
  if (authorization !== null) headers.set("authorization", authorization);
  return {
    headers,
    signal: ctx.signal,
    timeoutMs: ctx.timeoutMs(),
    onHeader: (h) => h.forEach((value, key) => key.startsWith("cinevol-") && ctx.responseHeader.set(key, value)),
    onTrailer: (t) => t.forEach((value, key) => key.startsWith("cinevol-") && ctx.responseTrailer.set(key, value)),
  };
}

/** A failure to reach the server says so in words, without the server's address or the system's error text. */
export function fromServer(e: unknown): ConnectError {
  const error = ConnectError.from(e);
  const cause = (error.cause as { code?: string } | undefined)?.code;
  if (cause && /^E[A-Z]+$/.test(cause)) {
    return new ConnectError(`cinevol-web cannot reach the render server (${cause})`, Code.Unavailable);
  }
  return error;
}

type Method = (request: unknown, options: CallOptions) => unknown;

/** Which server a call goes to: --server, or the session's own pod (SessionRoutes). */
export type PickTransport = (ctx: HandlerContext) => Transport;

export function forwardService(router: ConnectRouter, service: DescService, pick: PickTransport): void {
  const clients = new WeakMap<Transport, Record<string, Method>>();
  const clientFor = (transport: Transport) => {
    let client = clients.get(transport);
    if (!client) clients.set(transport, client = createClient(service, transport) as unknown as Record<string, Method>);
    return client;
  };
  const impl: Record<string, unknown> = {};
  for (const method of service.methods) {
    const call = (request: unknown, ctx: HandlerContext) => clientFor(pick(ctx))[method.localName](request, passThrough(ctx));
    if (method.methodKind === "unary") {
      impl[method.localName] = async (request: unknown, ctx: HandlerContext) => {
        try {
          return await call(request, ctx);
        } catch (e) {
          throw fromServer(e);
        }
      };
    } else if (method.methodKind === "server_streaming") {
      impl[method.localName] = async function* (request: unknown, ctx: HandlerContext) {
        try {
          yield* call(request, ctx) as AsyncIterable<unknown>;
        } catch (e) {
          throw fromServer(e);
        }
      };
    }
  }
  router.service(service, impl as never);  // built from the descriptor: the types cannot follow
}

/** The header a page sets to the address CreateSession answered (CreateSessionResponse.address). */
export const SESSION_ADDRESS_HEADER = "cinevol-session-address";
const MAX_ROUTES = 256;

/** Whether a session's address is one --session-hosts allows: a host of whole labels under a suffix, on its port. */
export function isSessionHost(address: string, hosts: SessionHost[]): boolean {
  const m = /^((?:[a-z0-9-]+\.)*[a-z0-9-]+):(\d{1,5})$/i.exec(address);
  if (!m) return false;
  const host = m[1].toLowerCase(), port = Number(m[2]);
  return hosts.some((h) => port === h.port && (host === h.suffix || host.endsWith("." + h.suffix)));
}

/**
 * Behind a load balancer a session lives on one server, which CreateSession
 * names; the page sends that address back with the session's calls. The
 * gateway goes there only when the host lies under one of the operator's
 * suffixes, on that suffix's port (--session-hosts), so no caller can point it
 * anywhere else.
 */
export class SessionRoutes {
  private readonly transports = new Map<string, Transport>();

  constructor(private readonly fallback: Transport, private readonly hosts: SessionHost[],
              private readonly make: (address: string) => Transport) {}

  pick(ctx: HandlerContext): Transport {
    const address = ctx.requestHeader.get(SESSION_ADDRESS_HEADER);
    if (!address || this.hosts.length === 0) return this.fallback;
    if (!isSessionHost(address, this.hosts)) {
      throw new ConnectError(`${SESSION_ADDRESS_HEADER}: cinevol-web does not route to '${address}' (--session-hosts)`,
                             Code.PermissionDenied);
    }
    let transport = this.transports.get(address);
    if (!transport) {
      if (this.transports.size >= MAX_ROUTES) this.transports.delete(this.transports.keys().next().value!);
      this.transports.set(address, transport = this.make(address));
    }
    return transport;
  }
}

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

export function forwardService(router: ConnectRouter, service: DescService, transport: Transport): void {
  const client = createClient(service, transport) as unknown as Record<string, Method>;
  const impl: Record<string, unknown> = {};
  for (const method of service.methods) {
    const call = client[method.localName];
    if (method.methodKind === "unary") {
      impl[method.localName] = async (request: unknown, ctx: HandlerContext) => {
        try {
          return await call(request, passThrough(ctx));
        } catch (e) {
          throw fromServer(e);
        }
      };
    } else if (method.methodKind === "server_streaming") {
      impl[method.localName] = async function* (request: unknown, ctx: HandlerContext) {
        try {
          yield* call(request, passThrough(ctx)) as AsyncIterable<unknown>;
        } catch (e) {
          throw fromServer(e);
        }
      };
    }
  }
  router.service(service, impl as never);  // built from the descriptor: the types cannot follow
}

// Short-lived signed URLs for rendered volumes (docs/web.md, "Signed URLs for <img>"): an <img> sends no
// Authorization header, so a caller with a bearer token asks for one:
//   POST /dicom-web/signed-url   Authorization: Bearer T   {"url": "/dicom-web/{pacs}/studies/.../rendered3D?...",
//                                                            "expiresIn": 60}
//   -> {"url": ".../rendered3D?...&signature=CAPABILITY", "expires": "2026-...Z", "expiresIn": 60}
// and a GET of that URL, with no header, is served as that caller, for that resource (the same PACS, study,
// series, instance and kind; its query may differ), until it expires. The capability is 256 random bits; the
// token stays in this process's memory, never in a URL, and is checked with the server before a URL is made.
import { createHash, randomBytes } from "node:crypto";
import { createClient, type Transport } from "@connectrpc/connect";
import { ServerService } from "../gen/cinevol/v1/service_pb.js";
import {
  readRendered, Refusal, reply, scopeOf, SIGNATURE, splitUrl, statusOf, type Request, type Response,
} from "./rendered.js";

export const SIGNING_PATH = "/dicom-web/signed-url";

/** How long signed URLs last and how many are held (all in this process's memory). */
export interface SignedUrlLimits {
  maxLifetimeS: number;      // [1; 300] - the longest a caller may ask for, seconds
  defaultLifetimeS: number;  // [1; maxLifetimeS] - when the request names none
  maxAlive: number;          // [1; 1e5] - unexpired URLs held for everyone; past it new ones are refused (429)
  maxAlivePerToken: number;  // [1; maxAlive] - unexpired URLs held for one bearer token (429 past it)
}

export const DEFAULT_LIMITS: SignedUrlLimits = {
  maxLifetimeS: 300,
  defaultLifetimeS: 60,
  maxAlive: 10_000,
  maxAlivePerToken: 100,
};

interface Grant {
  authorization: string;  // the caller's Authorization header, as it came
  holder: string;         // SHA-256 of it: whose count the grant is in
  scope: string;          // scopeOf() of the resource it was made for
  expiresAtMs: number;
}

const sha256 = (text: string) => createHash("sha256").update(text).digest("hex");

export class SignedUrls {
  // By SHA-256 of the capability: a lookup by the secret itself could leak its prefix through timing.
  private readonly grants = new Map<string, Grant>();
  private readonly perHolder = new Map<string, number>();

  constructor(readonly limits: SignedUrlLimits = DEFAULT_LIMITS, private readonly now: () => number = Date.now,
              private readonly random: (bytes: number) => Buffer = randomBytes) {}

  /** A new capability for `scope`, served as `authorization`, for `lifetimeS` seconds; or a Refusal (429). */
  issue(authorization: string, scope: string, lifetimeS: number): { capability: string; expiresAtMs: number } {
    this.dropExpired();
    const holder = sha256(authorization), held = this.perHolder.get(holder) ?? 0;
    if (held >= this.limits.maxAlivePerToken) {
      throw new Refusal(429, `this token holds ${held} signed URLs that have not expired (at most ` +
                             `${this.limits.maxAlivePerToken}); they last ${this.limits.maxLifetimeS} s at most`);
    }
    if (this.grants.size >= this.limits.maxAlive) {
      throw new Refusal(429, `the gateway holds ${this.grants.size} signed URLs (at most ${this.limits.maxAlive}); ` +
                             "try again once some expire");
    }
    const capability = this.random(32).toString("base64url");
    const expiresAtMs = this.now() + lifetimeS * 1000;
    this.grants.set(sha256(capability), { authorization, holder, scope, expiresAtMs });
    this.perHolder.set(holder, held + 1);
    return { capability, expiresAtMs };
  }

  /** The Authorization header a capability stands for at `scope`: 401 unknown or expired, 403 another resource. */
  redeem(capability: string, scope: string): string {
    const key = sha256(capability), grant = this.grants.get(key);
    if (!grant) {
      throw new Refusal(401, "the signed URL is not one this gateway made, or it expired (they last " +
                             `${this.limits.maxLifetimeS} s at most): ask for another`);
    }
    if (grant.expiresAtMs <= this.now()) {
      this.drop(key, grant);
      throw new Refusal(401, `the signed URL expired at ${new Date(grant.expiresAtMs).toISOString()}: ask for another`);
    }
    if (grant.scope !== scope) {
      throw new Refusal(403, `the signed URL is for ${grant.scope}, not this resource`);
    }
    return grant.authorization;
  }

  /** URLs held now (expired ones included until the next issue drops them). */
  get size(): number {
    return this.grants.size;
  }

  private dropExpired(): void {
    const now = this.now();
    for (const [key, grant] of this.grants) if (grant.expiresAtMs <= now) this.drop(key, grant);
  }

  private drop(key: string, grant: Grant): void {
    this.grants.delete(key);
    const held = (this.perHolder.get(grant.holder) ?? 1) - 1;
    if (held > 0) this.perHolder.set(grant.holder, held);
    else this.perHolder.delete(grant.holder);
  }
}

/** What a signing request asks for: a rendered resource's path and query, and seconds; or a Refusal (400). */
export function readSigningRequest(body: string, limits: SignedUrlLimits): { url: string; scope: string;
                                                                               lifetimeS: number } {
  let asked: { url?: unknown; expiresIn?: unknown };
  try {
    asked = JSON.parse(body);
  } catch {
    throw new Refusal(400, 'the body is not JSON: {"url": "/dicom-web/...", "expiresIn": seconds}');
  }
  const url = asked?.url, lifetimeS = asked?.expiresIn ?? limits.defaultLifetimeS;
  if (typeof url !== "string" || !url.startsWith("/dicom-web/")) {
    throw new Refusal(400, "url: the path of a rendered resource, /dicom-web/{pacs}/studies/...; no scheme or host");
  }
  if (typeof lifetimeS !== "number" || !Number.isInteger(lifetimeS) || lifetimeS < 1 ||
      lifetimeS > limits.maxLifetimeS) {
    throw new Refusal(400, `expiresIn: whole seconds, 1 to ${limits.maxLifetimeS}`);
  }
  const [path, search] = splitUrl(url);
  if (new URLSearchParams(search).has(SIGNATURE)) throw new Refusal(400, `url: already carries a ${SIGNATURE}`);
  let request;
  try {
    request = readRendered(path, search);
  } catch (e) {
    if (e instanceof Refusal) throw new Refusal(400, `url: ${e.message}`);
    throw e;
  }
  if (!request) throw new Refusal(400, "url: not a rendered resource");
  return { url, scope: scopeOf(request), lifetimeS };
}

const MAX_BODY_BYTES = 8 << 10;

/** A request whose body can be read (node's HTTP/1.1 and HTTP/2 requests alike). */
interface BodyRequest extends Request {
  [Symbol.asyncIterator](): AsyncIterator<Buffer | string>;
}

async function readBody(req: BodyRequest): Promise<string> {
  const parts: Buffer[] = [];
  let bytes = 0;
  for await (const part of req) {
    const buffer = typeof part === "string" ? Buffer.from(part) : part;
    bytes += buffer.length;
    if (bytes > MAX_BODY_BYTES) throw new Refusal(413, `the body is larger than ${MAX_BODY_BYTES} bytes`);
    parts.push(buffer);
  }
  return Buffer.concat(parts).toString("utf8");
}

/**
 * Answers POST /dicom-web/signed-url: checks the caller's token with the server (GetStatus, as the caller), then
 * makes a capability for the resource asked; false where `req` is for another path.
 */
export function answerSigning(transport: Transport, urls: SignedUrls, req: BodyRequest, res: Response): boolean {
  if (splitUrl(req.url ?? "/")[0] !== SIGNING_PATH) return false;
  const authorization = req.headers.authorization;
  (async () => {
    if (req.method !== "POST") throw new Refusal(405, `${SIGNING_PATH} answers POST`);
    if (typeof authorization !== "string" || !/^Bearer \S+$/i.test(authorization)) {
      throw new Refusal(401, "a signed URL is made for a bearer token: send Authorization: Bearer TOKEN");
    }
    const asked = readSigningRequest(await readBody(req), urls.limits);
    // The token is the server's to judge: a URL made for one it refuses would only fill the gateway's memory.
    await createClient(ServerService, transport).getStatus({}, { headers: { authorization }, timeoutMs: 10_000 })
      .catch((e: unknown) => {
        const { status, message } = statusOf(e);
        throw new Refusal(status, message);
      });
    const { capability, expiresAtMs } = urls.issue(authorization, asked.scope, asked.lifetimeS);
    const url = `${asked.url}${asked.url.includes("?") ? "&" : "?"}${SIGNATURE}=${capability}`;
    return { url, expires: new Date(expiresAtMs).toISOString(), expiresIn: asked.lifetimeS };
  })().then(
    (made) => {
      if (res.writableEnded) return;
      const body = Buffer.from(JSON.stringify(made));
      res.writeHead(200, { "content-type": "application/json", "content-length": body.length,
                           "cache-control": "no-store", "x-content-type-options": "nosniff" });
      res.end(body);
    },
    (e: unknown) => {
      const { status, message } = e instanceof Refusal ? { status: e.status, message: e.message } : statusOf(e);
      if (!res.writableEnded) reply(res, status, message);
    });
  return true;
}

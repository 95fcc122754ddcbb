// The page's files, read once at start into memory: a request can name only
// one of them, never a path on the disk. An IHE IID launch address is the
// page, once its query is checked (src/iid.ts).
import { readdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { IID_PATHS, readIid } from "../src/iid.js";

/** What serve() needs of a node request and response (HTTP/1.1 or HTTP/2 alike). */
interface Request {
  url?: string;
  method?: string;
}
interface Response {
  writeHead(status: number, headers: Record<string, string | number>): unknown;
  end(body: Buffer | string): unknown;
}

const TYPES: Record<string, string> = {
  ".html": "text/html; charset=utf-8",
  ".js": "text/javascript; charset=utf-8",
  ".css": "text/css; charset=utf-8",
  ".svg": "image/svg+xml",
  ".map": "application/json",
};

// The page loads only its own scripts and styles, talks only to this origin,
// decodes frames from blobs; the token stays in the fragment and no Referer carries the URL.
const HEADERS = {
  "content-security-policy": "default-src 'self'; img-src 'self' blob: data:; connect-src 'self'; " +
    "script-src 'self'; style-src 'self'; worker-src 'self'; object-src 'none'; base-uri 'none'; " +
    "frame-ancestors 'self'",
  "referrer-policy": "no-referrer",
  "x-content-type-options": "nosniff",
};

interface StaticFile {
  body: Buffer;
  type: string;
}

export class StaticFiles {
  private readonly files = new Map<string, StaticFile>();

  constructor(dir: string) {
    for (const name of readdirSync(dir)) {
      const type = TYPES[name.slice(name.lastIndexOf("."))];
      if (type) this.files.set("/" + name, { body: readFileSync(join(dir, name)), type });
    }
    if (!this.files.has("/index.html")) throw new Error(`--static ${dir}: no index.html (is the page built?)`);
  }

  /** Answers GET and HEAD of a page file (the query ignored), /healthz, and 404 or 405 otherwise. */
  serve(req: Request, res: Response): void {
    const path = (req.url ?? "/").split("?")[0];
    if (req.method !== "GET" && req.method !== "HEAD") {
      res.writeHead(405, { allow: "GET, HEAD", "content-type": "text/plain" });
      res.end("method not allowed\n");
      return;
    }
    if (path === "/healthz") {
      res.writeHead(200, { "content-type": "text/plain", "cache-control": "no-store" });
      res.end("ok\n");
      return;
    }
    if (IID_PATHS.includes(path)) {
      const iid = readIid(new URLSearchParams((req.url ?? "").slice(path.length + 1)));
      if (typeof iid === "string") {
        res.writeHead(400, { "content-type": "text/plain; charset=utf-8", "cache-control": "no-store" });
        res.end(`Invoke Image Display: ${iid}\n`);
        return;
      }
    }
    const file = this.files.get(path === "/" || IID_PATHS.includes(path) ? "/index.html" : path);
    if (!file) {
      res.writeHead(404, { "content-type": "text/plain" });
      res.end("not found\n");
      return;
    }
    res.writeHead(200, { ...HEADERS, "content-type": file.type, "content-length": file.body.length,
                         "cache-control": "no-cache" });
    res.end(req.method === "HEAD" ? "" : file.body);
  }
}

// A browser's XMLHttpRequest, as much of it as dicomweb-client uses, over node's fetch: the end-to-end tests run
// that client in node, which has none. Loopback only, as everything the tests send.

export class FetchXhr {
  readyState = 0;
  status = 0;
  response: unknown = null;
  responseType = "";
  withCredentials = false;
  onreadystatechange: (() => void) | null = null;
  onloadstart: (() => void) | null = null;
  onloadend: (() => void) | null = null;
  onprogress: (() => void) | null = null;
  private method = "GET";
  private url = "";
  private readonly headers = new Headers();
  private answer: Response | undefined;

  open(method: string, url: string): void {
    if (new URL(url).hostname !== "127.0.0.1") throw new Error(`the tests ask loopback only, not ${url}`);
    this.method = method.toUpperCase();
    this.url = url;
    this.readyState = 1;
  }

  setRequestHeader(name: string, value: string): void {
    this.headers.append(name, value);
  }

  getResponseHeader(name: string): string | null {
    return this.answer?.headers.get(name) ?? null;
  }

  getAllResponseHeaders(): string {
    return [...(this.answer?.headers ?? [])].map(([name, value]) => `${name}: ${value}\r\n`).join("");
  }

  send(body?: BodyInit): void {
    this.onloadstart?.();
    fetch(this.url, { method: this.method, headers: this.headers, body, signal: AbortSignal.timeout(120_000) })
      .then(async (answer) => {
        this.answer = answer;
        this.status = answer.status;
        if (this.responseType === "arraybuffer") {
          this.response = await answer.arrayBuffer();
        } else {
          const text = await answer.text();
          this.response = this.responseType === "json" ? parseOrNull(text) : text;
        }
      }, () => { this.status = 0; })
      .finally(() => {
        this.readyState = 4;
        this.onreadystatechange?.();
        this.onloadend?.();
      });
  }
}

function parseOrNull(text: string): unknown {
  try {
    return JSON.parse(text);
  } catch {
    return null;  // as a browser's XMLHttpRequest answers a body that is not JSON
  }
}

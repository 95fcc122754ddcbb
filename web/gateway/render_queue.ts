// Rendered requests wait their turn (docs/web.md, "Many callers"): each makes a session on the server, which holds a
// principal to --max-sessions-per-principal (16) and renders on shared devices, so a burst from one caller would be
// refused there, and would crowd out everyone else's. Here each caller (an Authorization header, or a signed URL's)
// has at most PER_CALLER renders in flight, all callers together AT_ONCE; the rest wait in a queue per caller, the
// callers served in turn (one request each, round-robin), so a burst waits behind its own earlier requests, never
// behind another caller's. A queue past its bound is refused (429), and a request whose client went away leaves it.
import { createHash } from "node:crypto";
import { Refusal } from "./rendered.js";

export interface QueueLimits {
  perCaller: number;         // renders in flight for one caller
  atOnce: number;            // renders in flight for all callers
  waitingPerCaller: number;  // requests one caller may have waiting
  waiting: number;           // requests waiting for all callers
}

export const DEFAULT_QUEUE_LIMITS: QueueLimits = { perCaller: 4, atOnce: 8, waitingPerCaller: 64, waiting: 512 };

interface Waiter {
  start: () => void;
}

interface Caller {
  running: number;
  waiting: Waiter[];
}

export class RenderQueue {
  private running = 0;
  private waiting = 0;
  private readonly callers = new Map<string, Caller>();
  private turns: string[] = [];  // callers with requests waiting, the next to be served first

  constructor(private readonly limits: QueueLimits = DEFAULT_QUEUE_LIMITS) {}

  /** Runs `work` once its caller's turn comes; a Refusal (429) where the queues are full, or `signal` aborts first. */
  async run<T>(authorization: string | undefined, signal: AbortSignal, work: () => Promise<T>): Promise<T> {
    const key = createHash("sha256").update(authorization ?? "").digest("hex");
    await this.turn(key, signal);
    try {
      return await work();
    } finally {
      this.finished(key);
    }
  }

  /** Requests in flight and waiting, for tests and logs. */
  get counts(): { running: number; waiting: number } {
    return { running: this.running, waiting: this.waiting };
  }

  private turn(key: string, signal: AbortSignal): Promise<void> {
    const caller = this.callers.get(key) ?? { running: 0, waiting: [] };
    this.callers.set(key, caller);
    if (caller.waiting.length === 0 && caller.running < this.limits.perCaller && this.running < this.limits.atOnce) {
      caller.running++;
      this.running++;
      return Promise.resolve();
    }
    if (caller.waiting.length >= this.limits.waitingPerCaller || this.waiting >= this.limits.waiting) {
      this.forgetIdle(key);
      return Promise.reject(new Refusal(429, caller.waiting.length >= this.limits.waitingPerCaller
        ? `this caller has ${caller.waiting.length} rendered requests waiting (at most ${this.limits.waitingPerCaller}); ` +
          "ask again once some are answered"
        : `the gateway has ${this.waiting} rendered requests waiting (at most ${this.limits.waiting}); ask again later`));
    }
    return new Promise((resolve, reject) => {
      const waiter: Waiter = { start: resolve };
      caller.waiting.push(waiter);
      this.waiting++;
      if (!this.turns.includes(key)) this.turns.push(key);
      signal.addEventListener("abort", () => {
        const at = caller.waiting.indexOf(waiter);
        if (at < 0) return;  // already started: the work sees the signal itself
        caller.waiting.splice(at, 1);
        this.waiting--;
        this.forgetIdle(key);
        reject(new Refusal(499, "the client went away while its request waited"));
      }, { once: true });
    });
  }

  private finished(key: string): void {
    const caller = this.callers.get(key)!;
    caller.running--;
    this.running--;
    this.forgetIdle(key);
    this.startWaiting();
  }

  /** Starts waiting requests while there is room: callers in turn, one request each, to the back of the line after. */
  private startWaiting(): void {
    for (let i = 0; i < this.turns.length && this.running < this.limits.atOnce;) {
      const key = this.turns[i], caller = this.callers.get(key);
      if (!caller || caller.waiting.length === 0) {
        this.turns.splice(i, 1);
        continue;
      }
      if (caller.running >= this.limits.perCaller) {
        i++;
        continue;
      }
      const waiter = caller.waiting.shift()!;
      this.waiting--;
      caller.running++;
      this.running++;
      this.turns.splice(i, 1);
      if (caller.waiting.length > 0) this.turns.push(key);
      waiter.start();
    }
  }

  private forgetIdle(key: string): void {
    const caller = this.callers.get(key);
    if (caller && caller.running === 0 && caller.waiting.length === 0) this.callers.delete(key);
  }
}

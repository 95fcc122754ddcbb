// What the stats overlay shows, measured in the page: frames painted per
// second, motion-to-photon (an input event to the first frame painted that
// includes it) p50/p95, and bytes received per second.

/** The p-quantile (0..1) by nearest rank; NaN for no samples. */
export function percentile(samples: readonly number[], p: number): number {
  if (samples.length === 0) return NaN;
  const sorted = [...samples].sort((a, b) => a - b);
  const rank = Math.min(sorted.length - 1, Math.max(0, Math.ceil(p * sorted.length) - 1));
  return sorted[rank];
}

/** Counts per second over a sliding window of `windowMs`. */
export class Rate {
  private events: { at: number; amount: number }[] = [];
  constructor(private readonly windowMs = 2000) {}
  add(at: number, amount = 1): void {
    this.events.push({ at, amount });
    this.trim(at);
  }
  perSecond(now: number): number {
    this.trim(now);
    const total = this.events.reduce((s, e) => s + e.amount, 0);
    return (total * 1000) / this.windowMs;
  }
  private trim(now: number): void {
    while (this.events.length > 0 && this.events[0].at <= now - this.windowMs) this.events.shift();
  }
}

/**
 * Motion-to-photon: each event's sequence number and when its input came;
 * a painted frame that includes events up to `lastSeq` closes them all
 * (later events absorb earlier ones, so every one counts from its own input).
 */
export class MotionToPhoton {
  private pending = new Map<bigint, number>();
  readonly samples: number[] = [];
  constructor(private readonly keep = 500) {}
  sent(seq: bigint, inputAt: number): void {
    this.pending.set(seq, inputAt);
  }
  painted(lastSeq: bigint, at: number): void {
    for (const [seq, inputAt] of this.pending) {
      if (seq > lastSeq) continue;
      this.samples.push(at - inputAt);
      this.pending.delete(seq);
    }
    if (this.samples.length > this.keep) this.samples.splice(0, this.samples.length - this.keep);
  }
  /** A new attach restarts sequence numbers: what was pending will never be answered. */
  reset(): void {
    this.pending.clear();
  }
}

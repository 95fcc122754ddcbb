// Shared pointers on the 3D view (docs/web.md, "Sharing a session"): where
// this page's pointer lies on the frame shown, as fractions of it, sent at
// most 20 times a second; everyone else's (SessionState.pointers) drawn as a
// small labelled marker. Pure functions and a throttle the tests drive.

/** Where a frame shows inside the view (CSS pixels from the view's top left). */
export interface FrameRect {
  left: number;
  top: number;
  width: number;
  height: number;
}

export interface Fraction {
  x: number;  // [0, 1) of the frame's width, right
  y: number;  // [0, 1) of its height, down
}

export interface Pointer {
  who: string;
  x: number;
  y: number;
}

/** The least time between two pointer events this page sends: 20 a second. */
export const POINTER_INTERVAL_MS = 50;

/** Where a `frame` (pixels) shows in a `box` (CSS pixels) that fits it whole and centred (object-fit: contain). */
export function fitted(box: { width: number; height: number }, frame: { width: number; height: number }): FrameRect {
  if (!frame.width || !frame.height) return { left: 0, top: 0, width: box.width, height: box.height };
  const fit = Math.min(box.width / frame.width, box.height / frame.height);
  const width = frame.width * fit, height = frame.height * fit;
  return { left: (box.width - width) / 2, top: (box.height - height) / 2, width, height };
}

/** A point of the view (CSS pixels from its top left) as fractions of the frame, or null off the frame. */
export function toFrame(p: { x: number; y: number }, rect: FrameRect): Fraction | null {
  const x = (p.x - rect.left) / rect.width, y = (p.y - rect.top) / rect.height;
  return x >= 0 && y >= 0 && x < 1 && y < 1 ? { x, y } : null;
}

/** The other way: fractions of the frame to the view's CSS pixels. */
export function fromFrame(f: Fraction, rect: FrameRect): { x: number; y: number } {
  return { x: rect.left + f.x * rect.width, y: rect.top + f.y * rect.height };
}

/** The pointers to draw: everyone's but one's own (`me`: one's name as the server writes it). */
export function othersPointers(pointers: readonly Pointer[], me: string | undefined): Pointer[] {
  return pointers.filter((p) => p.who !== me);
}

/**
 * One's own name as the server writes it, from its echo of the pointer this
 * page sent last: the one entry exactly there (the server keeps floats, so
 * the place comes back as sent). Undefined where none or several are.
 */
export function echoedName(pointers: readonly Pointer[], sent: Fraction | undefined): string | undefined {
  if (!sent) return undefined;
  const same = (a: number, b: number) => Math.abs(a - Math.fround(b)) < 1e-6;
  const there = pointers.filter((p) => same(p.x, sent.x) && same(p.y, sent.y));
  return there.length === 1 ? there[0].who : undefined;
}

/**
 * At most one value per `intervalMs`: the first goes at once, later ones
 * wait, and of those only the newest goes (so the last place, or a
 * `hidden`, always arrives).
 */
export class Throttle<T> {
  private last = -Infinity;
  private waiting: { value: T } | undefined;
  private timer = false;

  constructor(private readonly send: (value: T) => void, private readonly intervalMs = POINTER_INTERVAL_MS,
              private readonly clock: () => number = () => performance.now(),
              private readonly later: (run: () => void, ms: number) => void = (run, ms) => setTimeout(run, ms)) {}

  push(value: T): void {
    this.waiting = { value };
    if (this.timer) return;
    const wait = this.last + this.intervalMs - this.clock();
    if (wait <= 0) return this.flush();
    this.timer = true;
    this.later(() => {
      this.timer = false;
      this.flush();
    }, wait);
  }

  private flush(): void {
    const waiting = this.waiting;
    this.waiting = undefined;
    if (!waiting) return;
    this.last = this.clock();
    this.send(waiting.value);
  }
}

/** A marker and its holder's name for each pointer, where it lies on the frame shown. */
export function drawPointers(g: CanvasRenderingContext2D, pointers: readonly Pointer[], rect: FrameRect): void {
  g.font = "bold 12px system-ui, sans-serif";
  g.textBaseline = "middle";
  g.lineWidth = 2;
  for (const p of pointers) {
    const at = fromFrame(p, rect);
    g.fillStyle = "#ff3df5";
    g.strokeStyle = "#000";
    g.beginPath();
    g.arc(at.x, at.y, 6, 0, 2 * Math.PI);
    g.fill();
    g.stroke();
    g.strokeText(p.who, at.x + 10, at.y);
    g.fillStyle = "#fff";
    g.fillText(p.who, at.x + 10, at.y);
  }
}

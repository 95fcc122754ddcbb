// The 3D view: a canvas whose drawing belongs to the frame worker, sized in
// device pixels and following the window, and the pointer and touch input
// over it (as the desktop viewer: drag orbits, shift-drag or the middle
// button pans, the right button or the wheel zooms, alt-drag sets window and
// level, ctrl-drag turns the key light; one finger orbits, two pinch and pan;
// where the pointer is, for a shared session's pointers).
import type { Frame } from "../gen/cinevol/v1/service_pb.js";
import { dragZoomFactor, wheelZoomFactor } from "./camera.js";
import type { FrameMeta, FromWorker, ToWorker } from "./frame_messages.js";
import { fitted, toFrame, type Fraction, type FrameRect } from "./pointers.js";

export interface ViewInput {
  orbit(dx: number, dy: number): void;
  pan(dx: number, dy: number, heightCss: number): void;
  zoom(factor: number): void;
  windowLevel(dx: number, dy: number): void;
  turnLight(dx: number, dy: number): void;
  /**
   * A click without a drag: where on the frame shown, as fractions of its
   * width and height (x right, y down), and that frame's size.
   */
  pick(fx: number, fy: number, frame: { width: number; height: number }): void;
  /** Where the pointer is on the frame shown, with or without a button down; null once it leaves the frame. */
  point(at: Fraction | null): void;
}

const MAX_SIDE = 8192;
const RESIZE_SETTLE_MS = 150;
const CLICK_SLOP_PX = 4;  // a press that moves less than this is a click (a pick), not a drag

export class View {
  private readonly worker: Worker;
  private samples = new Map<number, (s: { width: number; height: number; grid: number[] }) => void>();
  private nextSample = 1;
  onPainted: (meta: FrameMeta, at: number, decodeMs: number, replaced: number) => void = () => {};
  /** When the newest pointer, wheel or key event happened (the page's clock, ms since the epoch). */
  inputAt = 0;
  private frameSize = { width: 0, height: 0 };  // the newest frame painted
  onError: (text: string) => void = () => {};

  constructor(readonly canvas: HTMLCanvasElement) {
    this.worker = new Worker(new URL("./frame-worker.js", import.meta.url), { type: "module" });
    const offscreen = canvas.transferControlToOffscreen();
    this.post({ kind: "canvas", canvas: offscreen }, [offscreen]);
    this.worker.onmessage = (e: MessageEvent<FromWorker>) => {
      const m = e.data;
      if ("painted" in m) {
        this.frameSize = { width: m.painted.width, height: m.painted.height };
        this.onPainted(m.painted, m.at, m.decodeMs, m.replaced);
      }
      else if ("error" in m) this.onError(m.error);
      else this.samples.get(m.id)?.(m.sample), this.samples.delete(m.id);
    };
  }

  private post(message: ToWorker, transfer: Transferable[] = []): void {
    this.worker.postMessage(message, transfer);
  }

  show(frame: Frame): void {
    const image = frame.image;
    if (image.case === undefined) return;
    const bytes = image.value.slice().buffer;  // a copy the worker owns
    const meta: FrameMeta = { id: frame.frameId, lastEventSeq: frame.lastEventSeq, width: frame.width,
                              height: frame.height, bytes: image.value.byteLength, final: frame.final };
    this.post({ kind: "frame", bytes, type: image.case === "png" ? "image/png" : "image/jpeg", meta }, [bytes]);
  }

  /** The picture now, as mean luminance on a cells x cells grid (tests compare these). */
  sample(cells = 16): Promise<{ width: number; height: number; grid: number[] }> {
    const id = this.nextSample++;
    return new Promise((resolve) => {
      this.samples.set(id, resolve);
      this.post({ kind: "sample", cells, id });
    });
  }

  /** The canvas's size in device pixels: the viewport to ask the server for. */
  devicePixels(): { width: number; height: number } {
    const r = this.canvas.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
    const side = (css: number) => Math.min(MAX_SIDE, Math.max(16, Math.round(css * dpr)));
    return { width: side(r.width), height: side(r.height) };
  }

  /** Calls `resized` with the device-pixel size once the window has stopped changing for a moment. */
  followSize(resized: (size: { width: number; height: number }) => void): void {
    let timer: ReturnType<typeof setTimeout> | undefined;
    new ResizeObserver(() => {
      clearTimeout(timer);
      timer = setTimeout(() => resized(this.devicePixels()), RESIZE_SETTLE_MS);
    }).observe(this.canvas);
  }

  listen(input: ViewInput): void {
    const c = this.canvas;
    const pointers = new Map<number, { x: number; y: number }>();
    let mode: "orbit" | "pan" | "zoom" | "windowLevel" | "light" = "orbit";
    c.addEventListener("contextmenu", (e) => e.preventDefault());
    c.addEventListener("pointerdown", (e) => {
      c.setPointerCapture(e.pointerId);
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
      mode = e.button === 1 || (e.button === 0 && e.shiftKey) ? "pan"
           : e.button === 2 ? "zoom"
           : e.altKey ? "windowLevel"
           : e.ctrlKey ? "light" : "orbit";
    });
    let travelled = 0;
    c.addEventListener("pointerdown", () => { travelled = 0; });
    c.addEventListener("pointerup", (e) => {
      pointers.delete(e.pointerId);
      const plain = e.button === 0 && !e.shiftKey && !e.altKey && !e.ctrlKey;
      const at = this.frameFraction(e);
      if (plain && travelled <= CLICK_SLOP_PX && at) input.pick(at.x, at.y, this.frameSize);
    });
    c.addEventListener("pointercancel", (e) => pointers.delete(e.pointerId));
    const stamp = (e: Event) => { this.inputAt = performance.timeOrigin + e.timeStamp; };
    for (const type of ["pointerdown", "pointermove", "wheel"]) c.addEventListener(type, stamp, { capture: true });
    window.addEventListener("keydown", stamp, { capture: true });
    c.addEventListener("pointermove", (e) => {
      if (e.pointerType !== "touch") input.point(this.frameFraction(e));
      const before = pointers.get(e.pointerId);
      if (!before) return;
      if (pointers.size === 2) return this.pinch(pointers, e, input);
      const dx = e.clientX - before.x, dy = e.clientY - before.y;
      travelled += Math.hypot(dx, dy);
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
      if (mode === "orbit") input.orbit(dx, dy);
      else if (mode === "pan") input.pan(dx, dy, c.clientHeight);
      else if (mode === "zoom") input.zoom(dragZoomFactor(dy));
      else if (mode === "windowLevel") input.windowLevel(dx, dy);
      else input.turnLight(dx, dy);
    });
    c.addEventListener("pointerleave", () => input.point(null));
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      input.zoom(wheelZoomFactor(-e.deltaY / 100));
    }, { passive: false });
  }

  /** Where a pointer is on the frame, as fractions: the canvas shows the frame fitted whole (object-fit: contain). */
  frameFraction(e: { clientX: number; clientY: number }): Fraction | null {
    const box = this.canvas.getBoundingClientRect(), rect = this.frameRect();
    return rect ? toFrame({ x: e.clientX - box.left, y: e.clientY - box.top }, rect) : null;
  }

  /** Where the newest frame painted shows in the canvas (CSS pixels from its top left); null before the first. */
  frameRect(): FrameRect | null {
    const { width, height } = this.frameSize;
    if (!width || !height) return null;
    return fitted(this.canvas.getBoundingClientRect(), this.frameSize);
  }

  /** Two fingers: their spread zooms, their midpoint pans. */
  private pinch(pointers: Map<number, { x: number; y: number }>, e: PointerEvent, input: ViewInput): void {
    const [a, b] = [...pointers.values()];
    const spread = Math.hypot(a.x - b.x, a.y - b.y), mid = { x: (a.x + b.x) / 2, y: (a.y + b.y) / 2 };
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    const [c, d] = [...pointers.values()];
    const spreadAfter = Math.hypot(c.x - d.x, c.y - d.y), midAfter = { x: (c.x + d.x) / 2, y: (c.y + d.y) / 2 };
    if (spread > 0 && spreadAfter > 0) input.zoom(spread / spreadAfter);
    input.pan(midAfter.x - mid.x, midAfter.y - mid.y, this.canvas.clientHeight);
  }
}

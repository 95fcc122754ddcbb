// The statistics over the 3D view (F2) and what tests read of the frames:
// frames painted a second and replaced before painting, motion-to-photon,
// bytes received a second, decode and draw, and the server's stage times.
import type { Frame } from "../gen/cinevol/v1/service_pb.js";
import type { FrameMeta } from "./frame_messages.js";
import { now } from "./session.js";
import { MotionToPhoton, percentile, Rate } from "./stats.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export class StatsPanel {
  readonly latency = new MotionToPhoton();
  private readonly paintedRate = new Rate();
  private readonly received = new Rate();
  private readonly decodeMs: number[] = [];  // the worker's decode and draw of each frame painted, newest last
  private readonly frameIds: number[] = [];  // the frames painted, newest last (tests compare a watcher's with the owner's)
  private lastFrame?: Frame;
  lastPainted?: FrameMeta;
  private replaced = 0;
  framesPainted = 0;

  constructor() {
    $("show-stats").addEventListener("change", () => this.showOrHide());
    setInterval(() => this.draw(), 250);
  }

  /** F2: the statistics shown or hidden. */
  toggle(): void {
    const box = $<HTMLInputElement>("show-stats");
    box.checked = !box.checked;
    this.showOrHide();
  }

  private showOrHide(): void {
    $("stats").hidden = !$<HTMLInputElement>("show-stats").checked;
  }

  /** A frame as it came off the stream (painted later, if no newer one replaces it). */
  arrived(frame: Frame): void {
    this.lastFrame = frame;
    this.received.add(now(), frame.image.value?.byteLength ?? 0);
  }

  painted(meta: FrameMeta, at: number, decodeMs: number, replaced: number): void {
    this.frameIds.push(Number(meta.id));
    if (this.frameIds.length > 64) this.frameIds.shift();
    this.decodeMs.push(decodeMs);
    if (this.decodeMs.length > 500) this.decodeMs.shift();
    this.lastPainted = meta;
    this.replaced = replaced;
    this.framesPainted += 1;
    this.paintedRate.add(at);
    this.latency.painted(meta.lastEventSeq, at);
    if (this.framesPainted === 1) this.draw();
  }

  private draw(): void {
    const f = this.lastFrame, t = f?.timings, ms = (us = 0) => (us / 1000).toFixed(1);
    const samples = this.latency.samples;
    $("stats").textContent = f ? [
      `${f.width}x${f.height}  frame ${f.frameId}  ${f.accumulatedSpp} spp${f.final ? "  final" : ""}` +
        (f.resolutionScale < 1 ? `  scale ${f.resolutionScale}` : ""),
      `${this.paintedRate.perSecond(now()).toFixed(1)} fps painted, ${this.replaced} replaced before painting`,
      `motion-to-photon p50 ${percentile(samples, 0.5).toFixed(0)} ms  p95 ${percentile(samples, 0.95).toFixed(0)} ms` +
        `  (${samples.length})`,
      `${(this.received.perSecond(now()) / 1e6).toFixed(2)} MB/s received, decode and draw p50 ` +
        `${percentile(this.decodeMs, 0.5).toFixed(1)} ms`,
      `server ms: render ${ms(t?.renderUs)} denoise ${ms(t?.denoiseUs)} tonemap ${ms(t?.tonemapUs)} ` +
        `encode ${ms(t?.encodeUs)} queue ${ms(t?.queueUs)} total ${ms(t?.serverUs)}`,
    ].join("\n") : "";  // before a frame the line over the view says what the page waits for
  }

  /** What tests and scripts read of the frames (window.cinevol.status()). */
  status() {
    const samples = this.latency.samples, p = this.lastPainted;
    return {
      framesPainted: this.framesPainted,
      lastFrame: p ? { ...p, id: Number(p.id), lastEventSeq: Number(p.lastEventSeq) } : null,
      motionToPhoton: { p50: percentile(samples, 0.5), p95: percentile(samples, 0.95), count: samples.length },
      decodeMs: { p50: percentile(this.decodeMs, 0.5), p95: percentile(this.decodeMs, 0.95) },
      fps: this.paintedRate.perSecond(now()), bytesPerSecond: this.received.perSecond(now()),
      frameIds: [...this.frameIds],
    };
  }
}

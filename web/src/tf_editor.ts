// The transfer-function editor: the volume's histogram (log counts), the
// opacity curve in the points' colours, and its points. Click adds a point,
// drag moves one, right-click deletes one; every edit goes to the server as
// a transfer-function event, and what the server answers is drawn.
import type { TransferFunction } from "../gen/cinevol/v1/scene_pb.js";
import type { ValueHistogram } from "../gen/cinevol/v1/service_pb.js";
import { addPoint, deletePoint, diffuseAt, movePoint, opacityAt } from "./transfer.js";

const HIT_RADIUS = 7;

export class TransferEditor {
  private tf?: TransferFunction;
  private histogram?: ValueHistogram;
  private dragging = -1;
  onEdit: (tf: TransferFunction) => void = () => {};

  constructor(private readonly canvas: HTMLCanvasElement, private readonly note: HTMLElement) {
    canvas.addEventListener("contextmenu", (e) => e.preventDefault());
    canvas.addEventListener("pointerdown", (e) => this.down(e));
    canvas.addEventListener("pointermove", (e) => this.move(e));
    canvas.addEventListener("pointerup", () => { this.dragging = -1; });
  }

  show(tf: TransferFunction | undefined, histogram?: ValueHistogram): void {
    if (histogram) this.histogram = histogram;
    if (this.dragging < 0 || !tf) this.tf = tf;  // mid-drag the page's own edit stays until the drag ends
    this.draw();
  }

  private range(): [number, number] {
    const h = this.histogram;
    if (h && h.maxValue > h.minValue) return [h.minValue, h.maxValue];
    const p = this.tf?.points ?? [];
    return p.length >= 2 ? [p[0].value, p[p.length - 1].value] : [0, 1];
  }

  private toValue(x: number): number {
    const [lo, hi] = this.range();
    return lo + (x / this.canvas.clientWidth) * (hi - lo);
  }

  private toX(value: number): number {
    const [lo, hi] = this.range();
    return ((value - lo) / (hi - lo)) * this.canvas.width;
  }

  private hit(e: PointerEvent): number {
    const sx = this.canvas.width / this.canvas.clientWidth, sy = this.canvas.height / this.canvas.clientHeight;
    const x = e.offsetX * sx, y = e.offsetY * sy;
    return (this.tf?.points ?? []).findIndex((p) =>
      Math.hypot(this.toX(p.value) - x, (1 - p.opacity) * this.canvas.height - y) <= HIT_RADIUS * sx);
  }

  private opacity(e: PointerEvent): number {
    return 1 - e.offsetY / this.canvas.clientHeight;
  }

  private down(e: PointerEvent): void {
    if (!this.tf) return;
    const index = this.hit(e);
    if (e.button === 2) {
      const edited = index >= 0 ? deletePoint(this.tf, index) : null;
      if (edited) this.edit(edited);
      return;
    }
    if (index >= 0) {
      this.dragging = index;
      this.canvas.setPointerCapture(e.pointerId);
      return;
    }
    const added = addPoint(this.tf, this.toValue(e.offsetX), this.opacity(e));
    if (added) {
      this.dragging = added.index;
      this.canvas.setPointerCapture(e.pointerId);
      this.edit(added.tf);
    }
  }

  private move(e: PointerEvent): void {
    if (this.dragging < 0 || !this.tf) return;
    const edited = movePoint(this.tf, this.dragging, this.toValue(e.offsetX), this.opacity(e));
    if (edited) this.edit(edited);
  }

  private edit(tf: TransferFunction): void {
    this.tf = tf;
    this.draw();
    this.onEdit(tf);
  }

  private draw(): void {
    const c = this.canvas, g = c.getContext("2d");
    if (!g) return;
    const { width: w, height: h } = c;
    g.clearRect(0, 0, w, h);
    const counts = this.histogram?.counts ?? [];
    const peak = Math.log1p(Math.max(1, ...counts.map(Number)));
    g.fillStyle = "#444";
    counts.forEach((n, i) => {
      const bar = (Math.log1p(Number(n)) / peak) * h;
      g.fillRect((i / counts.length) * w, h - bar, Math.ceil(w / counts.length), bar);
    });
    const tf = this.tf;
    this.note.textContent = !tf || tf.points.length === 0
      ? `${tf?.preset ? `Preset ${tf.preset}` : "The volume's default preset"}: click to add points.` : "";
    if (!tf || tf.points.length === 0) return;
    for (let x = 0; x < w; ++x) {
      const value = this.toValue((x / w) * c.clientWidth), d = diffuseAt(tf, value);
      g.fillStyle = `rgb(${255 * d.r},${255 * d.g},${255 * d.b})`;
      const y = (1 - opacityAt(tf, value)) * h;
      g.fillRect(x, y, 1, 2);
    }
    g.strokeStyle = "#fff";
    for (const p of tf.points) {
      g.beginPath();
      g.arc(this.toX(p.value), (1 - p.opacity) * h, 4, 0, 2 * Math.PI);
      g.stroke();
    }
  }
}

// One slice pane of the 2x2 layout: the server's slice through the
// crosshair (one request in flight and the newest next), drawn in
// millimetres with its edge letters, the crosshair and the measurements near
// its plane over it; its wheel steps the crosshair a voxel, a drag sets
// window and level, a click picks.
import type { MessageInitShape } from "@bufbuild/protobuf";
import { SliceAxis, type SliceImage, type SliceRequestSchema } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { measurementText, paneToPatient, patientToPane, shownSlice } from "./measure.js";
import type { Axis } from "./placement.js";
import type { FrameRect } from "./pointers.js";
import type { V3 } from "./vec.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const CLICK_SLOP_PX = 4;

/** What a pane asks of the reading tools it belongs to. */
export interface SliceReader {
  readonly api: Api;
  readonly crosshair?: V3;
  readonly measurements: readonly { points: V3[] }[];
  sliceRequest(spec: PaneSpec): (MessageInitShape<typeof SliceRequestSchema> & { positionMm: number }) | undefined;
  note(notice: string): void;
  error(text: string): void;
  voxelAcross(along: Axis): number;
  step(along: Axis, direction: number): void;
  dragWindow(dx: number, dy: number): void;
  picked(point: V3): void;
}

export interface PaneSpec {
  axis: SliceAxis;
  along: Axis;  // the patient axis the slice's position runs along
  element: string;
}

export const PANES: PaneSpec[] = [
  { axis: SliceAxis.AXIAL, along: "z", element: "slice-axial" },
  { axis: SliceAxis.CORONAL, along: "y", element: "slice-coronal" },
  { axis: SliceAxis.SAGITTAL, along: "x", element: "slice-sagittal" },
];

/** One slice view: its image, what the server said of its geometry, one request in flight and the newest next. */
export class Pane {
  image?: SliceImage;
  private url = "";
  private busy = false;
  private again = false;
  private readonly root: HTMLElement;
  private readonly img: HTMLImageElement;
  private readonly overlay: HTMLCanvasElement;

  constructor(readonly spec: PaneSpec, private readonly reading: SliceReader) {
    this.root = $(spec.element);
    this.img = this.root.querySelector("img")!;
    this.overlay = this.root.querySelector("canvas")!;
    this.listen();
  }

  async refresh(): Promise<void> {
    if (this.busy) {
      this.again = true;
      return;
    }
    this.busy = true;
    try {
      do {
        this.again = false;
        await this.fetch();
      } while (this.again);
    } finally {
      this.busy = false;
    }
  }

  private async fetch(): Promise<void> {
    const request = this.reading.sliceRequest(this.spec);
    if (!request) return;
    try {
      const image = await this.reading.api.sessions.renderSlice(request);
      URL.revokeObjectURL(this.url);
      this.url = URL.createObjectURL(new Blob([image.png.slice()], { type: "image/png" }));
      this.image = image;
      this.img.src = this.url;
      const name = SliceAxis[this.spec.axis];
      this.img.alt = `${name.toLowerCase()} slice at ${request.positionMm.toFixed(1)} mm`;
      const [left, right, top, bottom] = image.edgeLetters;
      for (const [edge, letter] of Object.entries({ left, right, top, bottom })) {
        this.part(`.edge-${edge}`).textContent = letter ?? "";
      }
      this.part(".slice-label").textContent = `${name} ${request.positionMm.toFixed(1)} mm`;
      this.part(".slice-window").textContent = `W ${image.window.toFixed(0)} L ${image.level.toFixed(0)}`;
      this.reading.note(image.notice);
      this.draw();
    } catch (e) {
      this.reading.error(plainWords(e));
    }
  }

  private part(selector: string): HTMLElement {
    return this.root.querySelector<HTMLElement>(selector)!;
  }

  /** Where the image shows in the pane now (CSS px from the pane's top left): in millimetres, fitted whole. */
  private shown(image: SliceImage): FrameRect {
    return shownSlice({ width: this.root.clientWidth, height: this.root.clientHeight }, image);
  }

  /** The image where it shows with its edge letters; over it the crosshair and the measurements near its plane. */
  draw(): void {
    const image = this.image, g = this.overlay.getContext("2d");
    if (!image || !g) return;
    const shown = this.shown(image);
    this.place(shown);
    const dpr = window.devicePixelRatio || 1;
    this.overlay.width = Math.round(this.root.clientWidth * dpr);
    this.overlay.height = Math.round(this.root.clientHeight * dpr);
    g.scale(dpr, dpr);
    const at = (p: V3) => patientToPane(image, shown, p);
    const cross = this.reading.crosshair;
    if (cross) {
      const c = at(cross);
      g.strokeStyle = "rgba(255, 220, 0, 0.7)";
      g.beginPath();
      g.moveTo(c.x, shown.top); g.lineTo(c.x, shown.top + shown.height);
      g.moveTo(shown.left, c.y); g.lineTo(shown.left + shown.width, c.y);
      g.stroke();
    }
    const near = this.reading.voxelAcross(this.spec.along);  // within a voxel of the plane, as the desktop viewer
    g.strokeStyle = g.fillStyle = "#4df";
    for (const m of this.reading.measurements) {
      const points = m.points.map(at);
      if (points.some((p) => Math.abs(p.offPlaneMm) > near)) continue;
      g.beginPath();
      points.forEach((p, i) => (i ? g.lineTo(p.x, p.y) : g.moveTo(p.x, p.y)));
      g.stroke();
      g.fillText(measurementText(m.points), points[points.length - 1].x + 6, points[points.length - 1].y);
    }
  }

  /** The image in its millimetre rectangle; each edge letter at the middle of its edge, inside it. */
  private place(shown: FrameRect): void {
    const px = (v: number) => `${v.toFixed(1)}px`;
    Object.assign(this.img.style, { left: px(shown.left), top: px(shown.top), width: px(shown.width),
                                    height: px(shown.height) });
    const right = shown.left + shown.width, bottom = shown.top + shown.height;
    const middle = { x: shown.left + shown.width / 2, y: shown.top + shown.height / 2 };
    const edges = { left: [shown.left, middle.y], right: [right, middle.y], top: [middle.x, shown.top],
                    bottom: [middle.x, bottom] };
    for (const [edge, [x, y]] of Object.entries(edges)) {
      Object.assign(this.part(`.edge-${edge}`).style, { left: px(x), top: px(y) });
    }
  }

  /** The patient position under a pointer, or null off the image. */
  private patientAt(e: PointerEvent): V3 | null {
    if (!this.image) return null;
    const box = this.root.getBoundingClientRect();
    return paneToPatient(this.image, this.shown(this.image), { x: e.clientX - box.left, y: e.clientY - box.top });
  }

  private listen(): void {
    const root = this.root;
    root.addEventListener("wheel", (e) => {
      e.preventDefault();
      this.reading.step(this.spec.along, Math.sign(e.deltaY));
    }, { passive: false });
    let down: { x: number; y: number } | undefined;
    root.addEventListener("pointerdown", (e) => {
      down = { x: e.clientX, y: e.clientY };
      root.setPointerCapture(e.pointerId);
    });
    root.addEventListener("pointermove", (e) => {
      if (!down || e.buttons === 0) return;
      this.reading.dragWindow(e.movementX, e.movementY);  // window and level, as on the desktop viewer's slices
    });
    root.addEventListener("pointerup", (e) => {
      const moved = down && Math.hypot(e.clientX - down.x, e.clientY - down.y) > CLICK_SLOP_PX;
      down = undefined;
      const p = moved ? null : this.patientAt(e);
      if (!p) return;
      $("pick-info").textContent = lps(p);
      this.reading.picked(p);
    });
  }
}


/** A patient position in words: "R 12.0 A 3.5 S 40.0 mm" (LPS signs turned into letters). */
export function lps(p: V3): string {
  const part = (v: number, plus: string, minus: string) => `${v >= 0 ? plus : minus} ${Math.abs(v).toFixed(1)}`;
  return `${part(p.x, "L", "R")} ${part(p.y, "P", "A")} ${part(p.z, "S", "I")} mm`;
}

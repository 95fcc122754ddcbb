// The reading tools in the page: axial, coronal and sagittal slices beside
// the 3D view (2x2), rendered by the server through a crosshair; picks on the
// 3D view and on slices; distance and angle measurements between picked
// points, drawn here and listed with their values (docs/reading.md).
import { Code, ConnectError } from "@connectrpc/connect";
import { SlabProjection, SliceAxis, type SliceImage, type VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { patientBox, slicePlaneOutline, spacingAlong } from "./geometry.js";
import { measurementText, paneToPatient, patientToPane, shownSlice } from "./measure.js";
import type { FrameRect } from "./pointers.js";
import { add, scale, v3, type V3 } from "./vec.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const CLICK_SLOP_PX = 4;

export interface Measurement {
  points: V3[];  // LPS mm: 2 a distance, 3 an angle
}

type SavedMeasurements = readonly { points: readonly { x: number; y: number; z: number }[] }[];

interface PaneSpec {
  axis: SliceAxis;
  along: "x" | "y" | "z";  // the patient axis the slice's position runs along
  element: string;
}

const PANES: PaneSpec[] = [
  { axis: SliceAxis.AXIAL, along: "z", element: "slice-axial" },
  { axis: SliceAxis.CORONAL, along: "y", element: "slice-coronal" },
  { axis: SliceAxis.SAGITTAL, along: "x", element: "slice-sagittal" },
];

/** One slice view: its image, what the server said of its geometry, one request in flight and the newest next. */
class Pane {
  image?: SliceImage;
  private url = "";
  private busy = false;
  private again = false;
  private readonly root: HTMLElement;
  private readonly img: HTMLImageElement;
  private readonly overlay: HTMLCanvasElement;

  constructor(readonly spec: PaneSpec, private readonly reading: Reading) {
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

export class Reading {
  crosshair?: V3;
  readonly measurements: Measurement[] = [];
  private measuring: { points: V3[]; wanted: number } | undefined;
  private window?: { width: number; level: number };
  private readonly panes: Pane[];
  private volume?: VolumeInfo;
  /** Called when what the 3D view draws over itself changes: the measurements, the crosshair's slice planes. */
  onOverlayChanged: () => void = () => {};
  /** Called when the reader adds or deletes a measurement: the session's scene (and its watchers) get the list. */
  onMeasurementsEdited: (measurements: readonly Measurement[]) => void = () => {};
  /** Called once for each thing the server says of the slices (a window in HU on values that are not). */
  onNotice: (text: string) => void = () => {};
  private readonly noted = new Set<string>();

  /** A slice's notice, passed on the first time it is said. */
  note(notice: string): void {
    if (!notice || this.noted.has(notice)) return;
    this.noted.add(notice);
    this.onNotice(notice);
  }

  constructor(readonly api: Api, private readonly sessionId: () => string | undefined,
              readonly error: (text: string) => void) {
    this.panes = PANES.map((spec) => new Pane(spec, this));
    $("layout").addEventListener("click", () => this.toggleLayout());
    for (const id of ["window-preset", "slab", "projection", "slice-clipping"]) {
      $(id).addEventListener("change", () => {
        if (id === "window-preset") this.window = undefined;
        this.refresh();
      });
    }
    $("measure-distance").addEventListener("click", () => this.startMeasuring(2));
    $("measure-angle").addEventListener("click", () => this.startMeasuring(3));
    new ResizeObserver(() => this.panes.forEach((p) => p.draw())).observe($("stage"));
  }

  get shown(): boolean {
    return $("stage").classList.contains("grid");
  }

  /** A new volume: the crosshair at its centre, no measurements yet. */
  setVolume(volume: VolumeInfo): void {
    this.volume = volume;
    const box = patientBox(volume);
    this.crosshair = scale(add(box.min, box.max), 0.5);
    this.measurements.length = 0;
    this.listMeasurements();
    this.offerStoredWindow(volume);
    this.refresh();
  }

  /** The window the volume's DICOM stores, as a choice of its own where there is one. */
  private offerStoredWindow(volume: VolumeInfo): void {
    const select = $<HTMLSelectElement>("window-preset");
    select.querySelector("option[value=stored]")?.remove();
    const w = volume.storedWindow;
    if (!w) {
      if (select.value === "stored") select.value = "";
      return;
    }
    select.add(new Option(`stored in the DICOM ${w.width}/${w.center}`, "stored"), 1);
  }

  /** Measurements a session's scene brought (a saved scene opened again), where the page has none yet. */
  restore(saved: SavedMeasurements): void {
    if (this.measurements.length > 0 || saved.length === 0) return;
    this.follow(saved);
  }

  /** The scene's measurements and no others: what a watcher of a shared session shows. */
  follow(saved: SavedMeasurements): void {
    this.measurements.splice(0, this.measurements.length,
                             ...saved.map((m) => ({ points: m.points.map((p) => v3(p.x, p.y, p.z)) })));
    this.listMeasurements();
  }

  refresh(): void {
    if (this.shown) for (const p of this.panes) void p.refresh();
    this.onOverlayChanged();
  }

  /** Where the three slices cut the volume, for the 3D view: each plane's outline (LPS mm); none unless shown. */
  slicePlanes(): { axis: SliceAxis; outline: V3[] }[] {
    const cross = this.crosshair, volume = this.volume;
    if (!this.shown || !cross || !volume) return [];
    return PANES.map((spec) => ({ axis: spec.axis, outline: slicePlaneOutline(volume, spec.along, cross[spec.along]) }));
  }

  sliceRequest(spec: PaneSpec) {
    const sessionId = this.sessionId();
    if (!sessionId || !this.crosshair) return undefined;
    const preset = $<HTMLSelectElement>("window-preset").value;
    return {
      sessionId, axis: spec.axis, positionMm: this.crosshair[spec.along],
      ...(this.window ? { window: this.window.width, level: this.window.level } : { windowPreset: preset }),
      slabMm: Number($<HTMLInputElement>("slab").value) || 0,
      projection: Number($<HTMLSelectElement>("projection").value) as SlabProjection,
      applyClipping: $<HTMLInputElement>("slice-clipping").checked,
    };
  }

  /** One voxel across a slice's plane (mm): the spacing of the volume's index axis along that patient axis. */
  voxelAcross(along: "x" | "y" | "z"): number {
    return this.volume ? spacingAlong(this.volume, along) : 1;
  }

  step(along: "x" | "y" | "z", direction: number): void {
    if (!this.crosshair) return;
    this.crosshair = { ...this.crosshair, [along]: this.crosshair[along] + direction * this.voxelAcross(along) };
    this.refresh();
  }

  dragWindow(dx: number, dy: number): void {
    const image = this.panes.find((p) => p.image)?.image;
    if (!image) return;
    const w = this.window ?? { width: image.window, level: image.level };
    this.window = { width: Math.max(1, w.width * Math.exp(dx * 0.01)), level: w.level - dy * Math.max(1, w.width / 200) };
    this.refresh();
  }

  /** A picked point (from the 3D view or a slice): the crosshair goes there, and a measurement takes it. */
  picked(point: V3): void {
    this.crosshair = point;
    if (this.measuring) {
      this.measuring.points.push(point);
      if (this.measuring.points.length === this.measuring.wanted) {
        this.measurements.push({ points: this.measuring.points });
        this.measuring = undefined;
        this.listMeasurements();
        this.onMeasurementsEdited(this.measurements);
      }
    }
    this.refresh();
    this.panes.forEach((p) => p.draw());
  }

  /** Asks the server what lies under pixel (x, y) of the frame shown, of size `frame` (a resize may be on its way). */
  async pickOnView(x: number, y: number, frame: { width: number; height: number }): Promise<void> {
    const sessionId = this.sessionId();
    if (!sessionId) return;
    try {
      const hit = await this.api.sessions.pick({ sessionId, x, y, frame });
      if (!hit.hit || !hit.positionMm) {
        $("pick-info").textContent = "Nothing there: the ray met no tissue at this opacity.";
        return;
      }
      const p = v3(hit.positionMm.x, hit.positionMm.y, hit.positionMm.z);
      const unit = this.volume?.valueUnit ? ` ${this.volume.valueUnit}` : "";
      $("pick-info").textContent = `${lps(p)} · ${hit.value.toFixed(0)}${unit}` +
        (hit.label ? ` · label ${hit.label.value}${hit.label.name ? ` ${hit.label.name}` : ""}` : "");
      this.picked(p);
    } catch (e) {
      const error = ConnectError.from(e);
      this.error(error.code === Code.Unimplemented ? "This server cannot pick (it is older than this page)." : plainWords(e));
    }
  }

  private startMeasuring(points: number): void {
    this.measuring = { points: [], wanted: points };
    $("pick-info").textContent = `Measuring: click ${points} points on the 3D view or the slices.`;
  }

  private listMeasurements(): void {
    $("measurements").replaceChildren(...this.measurements.map((m, i) => {
      const li = document.createElement("li"), remove = document.createElement("button");
      li.textContent = `${m.points.length === 2 ? "Distance" : "Angle"} ${measurementText(m.points)} `;
      remove.type = "button";
      remove.textContent = "Delete";
      remove.setAttribute("aria-label", `Delete measurement ${i + 1}`);
      remove.addEventListener("click", () => {
        this.measurements.splice(i, 1);
        this.listMeasurements();
        this.panes.forEach((p) => p.draw());
        this.onMeasurementsEdited(this.measurements);
      });
      li.append(remove);
      return li;
    }));
    this.onOverlayChanged();
  }

  /** The 2x2 layout on or off (the button, or F3 as in the desktop viewer). */
  toggleLayout(): void {
    const grid = $("stage").classList.toggle("grid");
    $("layout").textContent = grid ? "3D view only" : "Slices beside the 3D view (2x2)";
    for (const spec of PANES) $(spec.element).hidden = !grid;
    this.refresh();
  }
}

/** A patient position in words: "R 12.0 A 3.5 S 40.0 mm" (LPS signs turned into letters). */
export function lps(p: V3): string {
  const part = (v: number, plus: string, minus: string) => `${v >= 0 ? plus : minus} ${Math.abs(v).toFixed(1)}`;
  return `${part(p.x, "L", "R")} ${part(p.y, "P", "A")} ${part(p.z, "S", "I")} mm`;
}

// The reading tools in the page: the 2x2 layout (axial, coronal and
// sagittal slices beside the 3D view, rendered by the server through a
// crosshair: slice_pane.ts), picks on the 3D view and on slices, and
// distance and angle measurements between picked points, listed with their
// values (docs/reading.md). Patient coordinates throughout; where the volume
// lies is the state's placement.
import { Code, ConnectError } from "@connectrpc/connect";
import { SlabProjection, SliceAxis, type VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { measurementText } from "./measure.js";
import { centre, samePlacement, slicePlaneOutline, spacingAlong, type Axis, type Placement } from "./placement.js";
import { lps, Pane, PANES, type PaneSpec, type SliceReader } from "./slice_pane.js";
import { v3, type V3 } from "./vec.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export interface Measurement {
  points: V3[];  // LPS mm: 2 a distance, 3 an angle
}

type SavedMeasurements = readonly { points: readonly { x: number; y: number; z: number }[] }[];

export class Reading implements SliceReader {
  crosshair?: V3;
  readonly measurements: Measurement[] = [];
  private measuring: { points: V3[]; wanted: number } | undefined;
  private window?: { width: number; level: number };
  private readonly panes: Pane[];
  private volume?: VolumeInfo;
  private placement?: Placement;
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
    this.crosshair = this.placement && centre(this.placement);
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

  /** Where the volume lies (the state's placement); a new place puts the crosshair at its centre. */
  place(placement: Placement | undefined): void {
    if (samePlacement(placement, this.placement)) return;
    this.placement = placement;
    this.crosshair = placement && centre(placement);
    this.refresh();
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
    const cross = this.crosshair, placement = this.placement;
    if (!this.shown || !cross || !placement) return [];
    return PANES.map((spec) => ({ axis: spec.axis, outline: slicePlaneOutline(placement, spec.along, cross[spec.along]) }));
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
  voxelAcross(along: Axis): number {
    return this.placement ? spacingAlong(this.placement, along) : 1;
  }

  step(along: Axis, direction: number): void {
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


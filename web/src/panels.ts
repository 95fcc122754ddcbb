// The smaller panels: the labels of a segmentation (visibility, and the CT
// table's removal), the output (lossless final frame, JPEG quality while
// moving, the scene saved as a file), and the patient and study in the 3D
// view's corners (F4).
import { create, toJsonString } from "@bufbuild/protobuf";
import { LabelsSchema, LabelStyleSchema, MeasurementSchema, SceneSchema, Vec3Schema, type Scene } from "../gen/cinevol/v1/scene_pb.js";
import { FinalFormat, StreamSettingsSchema, type SessionState, type VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import { identityCorners } from "./identity.js";
import type { PageLink } from "./page_link.js";
import type { Measurement } from "./reading.js";
import type { V3 } from "./vec.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const vec3 = (v: V3) => create(Vec3Schema, { x: v.x, y: v.y, z: v.z });

/** Measurements as the scene holds them (LPS mm). */
export function sceneMeasurements(list: readonly Measurement[]) {
  return list.map((m) => create(MeasurementSchema, { points: m.points.map(vec3) }));
}

export class LabelsPanel {
  constructor(private readonly link: PageLink) {
    $("remove-table").addEventListener("change", () => this.send());
  }

  /** A volume described: a box for each of its segmentation's labels; the panel only where there is something to show. */
  setVolume(volume: VolumeInfo | undefined): void {
    const names = volume?.labels?.names ?? [];
    $("labels-panel").hidden = names.length === 0 && !volume?.table?.voxels;
    $("labels").replaceChildren(...names.filter((n) => n.value !== 0).map((n) => {
      const item = document.createElement("li"), label = document.createElement("label");
      const box = Object.assign(document.createElement("input"), { type: "checkbox", checked: true });
      box.dataset.label = String(n.value);
      box.addEventListener("change", () => this.send());
      label.append(box, ` ${n.value} ${n.name || "(unnamed)"}`);
      item.append(label);
      return item;
    }));
  }

  show(scene: Scene): void {
    if (this.link.ahead("labels")) return;
    for (const box of document.querySelectorAll<HTMLInputElement>("#labels input[data-label]")) {
      const style = scene.labels?.styles.find((s) => s.value === Number(box.dataset.label));
      box.checked = style?.visible ?? true;
    }
    $<HTMLInputElement>("remove-table").checked = scene.labels?.removeTable ?? false;
  }

  /** The state's label styles with each box's visibility. */
  private send(): void {
    const current = this.link.state?.scene?.labels;
    const styles = (current?.styles ?? []).map((s) => ({ ...s }));
    for (const box of document.querySelectorAll<HTMLInputElement>("#labels input[data-label]")) {
      const value = Number(box.dataset.label);
      let style = styles.find((s) => s.value === value);
      if (!style) styles.push(style = create(LabelStyleSchema, { value }));
      style.visible = box.checked;
    }
    this.link.post({ case: "labels", value: create(LabelsSchema, { ...current, styles,
                                                                    removeTable: $<HTMLInputElement>("remove-table").checked }) });
  }
}

export class OutputPanel {
  /** `measurements`: this page's own, saved with the scene. */
  constructor(private readonly link: PageLink, private readonly measurements: () => readonly Measurement[]) {
    $("lossless").addEventListener("change", () => this.link.post({ case: "stream", value: create(StreamSettingsSchema, {
      finalFormat: $<HTMLInputElement>("lossless").checked ? FinalFormat.PNG : FinalFormat.JPEG }) }));
    $("quality").addEventListener("change", () => this.link.post({ case: "stream", value: create(StreamSettingsSchema, {
      jpegQuality: Number($<HTMLInputElement>("quality").value) }) }));
    $("save-scene").addEventListener("click", () => this.saveScene());
  }

  show(state: SessionState): void {
    $<HTMLInputElement>("lossless").checked = state.stream?.finalFormat === FinalFormat.PNG;
    $<HTMLInputElement>("quality").value = String(state.stream?.jpegQuality ?? 80);
  }

  /** The scene as the server has it, with this page's measurements: a file cinevol render, the viewer and a session open. */
  private saveScene(): void {
    const scene = this.link.state?.scene;
    if (!scene) return;
    const saved = create(SceneSchema, scene);
    saved.measurements = sceneMeasurements(this.measurements());
    const link = document.createElement("a");
    link.href = URL.createObjectURL(new Blob([toJsonString(SceneSchema, saved, { prettySpaces: 2 })],
                                             { type: "application/json" }));
    link.download = "cinevol-scene.json";
    link.click();
    setTimeout(() => URL.revokeObjectURL(link.href), 1000);
  }
}

/** A DICOM volume's patient, study and series in the 3D view's corners, unless the user hid them (F4). */
export class IdentityCorners {
  private volume?: VolumeInfo;

  constructor() {
    $("show-identity").addEventListener("change", () => this.show());
  }

  setVolume(volume: VolumeInfo | undefined): void {
    this.volume = volume;
    this.show();
  }

  /** F4. */
  toggle(): void {
    const box = $<HTMLInputElement>("show-identity");
    box.checked = !box.checked;
    this.show();
  }

  private show(): void {
    const id = this.volume?.identity;
    $<HTMLInputElement>("show-identity").disabled = !id;
    const corners = id ? identityCorners(id) : { topLeft: [], topRight: [] };
    $("identity-top-left").textContent = corners.topLeft.join("\n");
    $("identity-top-right").textContent = corners.topRight.join("\n");
    $("identity").hidden = !id || !$<HTMLInputElement>("show-identity").checked;
  }
}

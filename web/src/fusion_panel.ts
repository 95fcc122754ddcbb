// A second volume fused with the session's (Scene.fusion; docs/time-and-fusion.md): opened with the page's
// `fuse=ID` address (and `align=patient` for volumes of different frames of reference), its controls change how
// it shows: the slices' overlay (colour map, opacity) and whether it glows in the 3D view. Shown only while the
// scene fuses one.
import { clone, create } from "@bufbuild/protobuf";
import {
  ColorMap, FusionOverlaySchema, FusionSchema, type Fusion, type Scene, type TransferFunction, TransferFunctionSchema,
} from "../gen/cinevol/v1/scene_pb.js";
import type { VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { PageLink } from "./page_link.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

/**
 * How the second volume glows in 3D: transparent below a threshold, emitting warm light above it. In SUVbw where
 * the volume has it (2.5 and up: the usual threshold of FDG uptake), else over the top 70% of its range.
 */
export function glowOf(volume: Pick<VolumeInfo, "minValue" | "maxValue" | "suvFactor">): TransferFunction {
  const suv = volume.suvFactor > 0;
  const lo = suv ? 2.5 : volume.minValue + 0.3 * (volume.maxValue - volume.minValue);
  const hi = suv ? 10 : volume.maxValue;
  const point = (value: number, opacity: number, glow: number) => ({
    value, opacity, diffuse: { r: 1, g: 0.4, b: 0.1 }, emission: { r: 6 * glow, g: 2.4 * glow, b: 0.5 * glow },
  });
  return create(TransferFunctionSchema, {
    points: [point(lo, 0, 0), point(Math.max(hi, lo + 1e-3), 0.4, 1)], densityScale: 1,
  });
}

/** The scene a page opened with `fuse=ID` starts from: the volume's default look, the second volume glowing. */
export function fusedStart(fused: VolumeInfo, alignByPatient: boolean): Fusion {
  return create(FusionSchema, {
    volumeId: fused.id, alignByPatient, suv: fused.suvFactor > 0, transferFunction: glowOf(fused),
    overlay: { colorMap: ColorMap.HOT, opacity: 0.5 },
  });
}

export class FusionPanel {
  private fusion?: Fusion;
  private fused?: VolumeInfo;

  /** `describe`: a volume's description from the server (the glow's values, after a reload). */
  constructor(private readonly link: PageLink, private readonly describe: (id: string) => Promise<VolumeInfo>) {
    for (const id of ["fusion-opacity", "fusion-map", "fusion-glow"]) $(id).addEventListener("input", () => this.send());
  }

  /** The second volume's description, for its glow's values. */
  setFused(volume: VolumeInfo | undefined): void {
    this.fused = volume;
  }

  /** The server's state: whether the scene fuses a second volume, and how it shows (an edit keeps its own while newer). */
  show(scene: Scene): void {
    this.fusion = scene.fusion;
    $("fusion").hidden = !this.fusion;
    if (!this.fusion || this.link.ahead("fusion")) return;
    const id = this.fusion.volumeId;
    if (this.fused?.id !== id) void this.describe(id).then((v) => this.setFused(v)).catch(() => {});
    $("fusion-name").textContent = this.fusion.volumeId;
    $<HTMLInputElement>("fusion-opacity").value = String(this.fusion.overlay?.opacity ?? 0.5);
    $<HTMLSelectElement>("fusion-map").value = ColorMap[this.fusion.overlay?.colorMap ?? ColorMap.HOT];
    $<HTMLInputElement>("fusion-glow").checked = (this.fusion.transferFunction?.points.length ?? 0) > 0;
  }

  private send(): void {
    if (!this.fusion) return;
    const fusion = clone(FusionSchema, this.fusion);
    fusion.overlay ??= create(FusionOverlaySchema);
    fusion.overlay.opacity = Number($<HTMLInputElement>("fusion-opacity").value);
    fusion.overlay.colorMap = ColorMap[$<HTMLSelectElement>("fusion-map").value as keyof typeof ColorMap];
    const glowing = $<HTMLInputElement>("fusion-glow").checked;
    fusion.transferFunction = glowing && this.fused ? glowOf(this.fused) : create(TransferFunctionSchema, {});
    this.link.post({ case: "fusion", value: fusion });
  }
}

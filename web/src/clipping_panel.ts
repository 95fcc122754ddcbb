// Crop and clip: a crop box from fractions of the volume's patient box
// along each patient axis, and a clip plane across the view at a depth from
// the target, with caps on the cut faces. Clipping is in patient
// coordinates; the camera's target and view move there through the state's
// placement.
import { create } from "@bufbuild/protobuf";
import { ClippingSchema, ClipPlaneSchema, CropBoxSchema, Vec3Schema, type Scene } from "../gen/cinevol/v1/scene_pb.js";
import type { ViewCamera } from "./camera.js";
import type { PageLink } from "./page_link.js";
import { cropFromFractions, directionToPatient, patientBox, toPatient } from "./placement.js";
import { add, norm, scale, sub, v3, type V3 } from "./vec.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const vec3 = (v: V3) => create(Vec3Schema, { x: v.x, y: v.y, z: v.z });
const AXES = ["x", "y", "z"] as const;
const AXIS_NAMES = { x: "Right–left", y: "Anterior–posterior", z: "Inferior–superior" };

export class ClippingPanel {
  /** `camera`: the camera the page shows (Navigation's). */
  constructor(private readonly link: PageLink, private readonly camera: () => ViewCamera | undefined) {
    for (const id of ["crop-on", "clip-on", "clip-depth", "caps"]) $(id).addEventListener("input", () => this.send());
    this.reset();
  }

  /** A new volume: the sliders span it whole again. */
  reset(): void {
    const holder = $("crop-sliders");
    holder.replaceChildren();
    for (const axis of AXES) {
      for (const end of ["lo", "hi"] as const) {
        const input = document.createElement("input");
        Object.assign(input, { type: "range", min: "0", max: "100", value: end === "lo" ? "0" : "100",
                               id: `crop-${axis}-${end}` });
        const name = `${AXIS_NAMES[axis]} crop ${end === "lo" ? "start" : "end"} (%)`;
        input.setAttribute("aria-label", name);
        input.title = name;
        input.addEventListener("input", () => this.send());
        holder.append(input);
      }
    }
  }

  show(scene: Scene): void {
    if (this.link.ahead("clipping")) return;
    $<HTMLInputElement>("crop-on").checked = Boolean(scene.clipping?.cropBox);
    $<HTMLInputElement>("clip-on").checked = (scene.clipping?.planes.length ?? 0) > 0;
  }

  private send(): void {
    const placement = this.link.placement, camera = this.camera();
    if (!placement || !camera) return;
    const fraction = (axis: string, end: string) => Number($<HTMLInputElement>(`crop-${axis}-${end}`).value) / 100;
    const caps = $<HTMLInputElement>("caps").checked;
    const clipping = create(ClippingSchema, {});
    if ($<HTMLInputElement>("crop-on").checked) {
      const lo = v3(fraction("x", "lo"), fraction("y", "lo"), fraction("z", "lo"));
      const hi = v3(fraction("x", "hi"), fraction("y", "hi"), fraction("z", "hi"));
      const { center, size } = cropFromFractions(patientBox(placement), lo, hi);
      clipping.cropBox = create(CropBoxSchema, { center: vec3(center), size: vec3(size), cap: caps });
    }
    if ($<HTMLInputElement>("clip-on").checked) {
      const along = norm(directionToPatient(placement, sub(camera.target, camera.eye)));
      const target = toPatient(placement, camera.target);
      const depth = Number($<HTMLInputElement>("clip-depth").value);
      clipping.planes = [create(ClipPlaneSchema, { point: vec3(add(target, scale(along, depth))), normal: vec3(along),
                                                   cap: caps })];
    }
    this.link.post({ case: "clipping", value: clipping });
  }
}

// The key light (the scene's first area light): its azimuth and elevation
// as the camera sees it and its intensity, set by the sliders or by
// Ctrl-drag, which turns it about the target like the eye.
import { create } from "@bufbuild/protobuf";
import { AreaLightSchema, LightSchema, Vec3Schema, type Light, type Scene } from "../gen/cinevol/v1/scene_pb.js";
import { LightListSchema } from "../gen/cinevol/v1/service_pb.js";
import { DEGREES_PER_PIXEL, lightDirection, setLightDirection, type ViewCamera } from "./camera.js";
import type { PageLink } from "./page_link.js";
import type { V3 } from "./vec.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const vec3 = (v: V3) => create(Vec3Schema, { x: v.x, y: v.y, z: v.z });
const value = (id: string) => Number($<HTMLInputElement>(id).value);

function keyLight(scene: Scene | undefined): { index: number; light: Light } | undefined {
  const index = scene?.lights.findIndex((l) => l.kind.case === "area") ?? -1;
  return index >= 0 ? { index, light: scene!.lights[index] } : undefined;
}

export class LightPanel {
  /** `camera`: the camera the page shows (Navigation's). */
  constructor(private readonly link: PageLink, private readonly camera: () => ViewCamera | undefined) {
    for (const id of ["light-azimuth", "light-elevation", "light-intensity"]) {
      $(id).addEventListener("input", () => this.set(value("light-azimuth"), value("light-elevation"),
                                                     value("light-intensity")));
    }
  }

  show(scene: Scene): void {
    const key = keyLight(scene), camera = this.camera();
    $("light").hidden = !key;
    if (!key || key.light.kind.case !== "area" || !camera || this.link.ahead("lights")) return;
    const area = key.light.kind.value;
    const d = lightDirection({ center: area.center!, edgeU: area.edgeU!, edgeV: area.edgeV! }, camera);
    $<HTMLInputElement>("light-azimuth").value = String(Math.round(d.azimuthDeg));
    $<HTMLInputElement>("light-elevation").value = String(Math.round(d.elevationDeg));
    $<HTMLInputElement>("light-intensity").value = String(area.intensity);
  }

  /** Ctrl-drag: the light turns as the eye would, the sliders with it. */
  turn(dx: number, dy: number): void {
    if (!this.link.driving) return;
    const azimuth = ((value("light-azimuth") + dx * DEGREES_PER_PIXEL + 540) % 360) - 180;
    const elevation = Math.max(-89, Math.min(89, value("light-elevation") - dy * DEGREES_PER_PIXEL));
    $<HTMLInputElement>("light-azimuth").value = String(azimuth);
    $<HTMLInputElement>("light-elevation").value = String(elevation);
    this.set(azimuth, elevation, value("light-intensity"));
  }

  private set(azimuthDeg: number, elevationDeg: number, intensity: number): void {
    const scene = this.link.state?.scene, key = keyLight(scene), camera = this.camera();
    if (!scene || !key || key.light.kind.case !== "area" || !camera) return;
    const area = key.light.kind.value;
    const pose = setLightDirection({ center: area.center!, edgeU: area.edgeU!, edgeV: area.edgeV! }, camera,
                                   azimuthDeg, elevationDeg);
    const turned = create(AreaLightSchema, { ...area, center: vec3(pose.center), edgeU: vec3(pose.edgeU),
                                             edgeV: vec3(pose.edgeV), intensity });
    const lights = scene.lights.map((l, i) =>
      i === key.index ? create(LightSchema, { kind: { case: "area", value: turned } }) : l);
    this.link.post({ case: "lights", value: create(LightListSchema, { lights }) });
  }
}

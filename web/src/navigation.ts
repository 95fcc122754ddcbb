// The camera the page drags from: the state's (always numbers: the server
// turns named views and frames), except while this page's own moves are
// newer than the state. Orbit, pan and zoom move it here and send it; a
// named view (A P L R S I) is asked of the server, about the current target
// at the current distance, and drags wait for its answer; Home sends back
// the camera the session had before the first move. And the orientation
// marker, which follows the camera.
import { create } from "@bufbuild/protobuf";
import { CameraSchema, NamedView, Vec3Schema, type Camera } from "../gen/cinevol/v1/scene_pb.js";
import type { SessionState } from "../gen/cinevol/v1/service_pb.js";
import { fromCamera, orbitByDrag, pan, zoom, type ViewCamera } from "./camera.js";
import { markerAxes } from "./orientation.js";
import type { PageLink } from "./page_link.js";
import type { V3 } from "./vec.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const vec3 = (v: V3) => create(Vec3Schema, { x: v.x, y: v.y, z: v.z });
const MARKER_COLOURS: Record<string, string> = { L: "#e66", R: "#e66", P: "#6c6", A: "#6c6", S: "#69f", I: "#69f" };

export type ViewName = "ANTERIOR" | "POSTERIOR" | "LEFT" | "RIGHT" | "SUPERIOR" | "INFERIOR";

export class Navigation {
  camera?: ViewCamera;
  private home?: ViewCamera;
  private turning = false;  // a named view asked for and not answered yet: a drag would undo it
  /** Called when the camera the page shows changes: what is drawn over the view follows it. */
  onMoved: () => void = () => {};

  constructor(private readonly link: PageLink) {}

  /** A new volume's session: Home becomes its first camera; until its first state there is none to show. */
  reset(): void {
    this.home = undefined;
    this.camera = undefined;
    this.turning = false;
  }

  adopt(state: SessionState): void {
    if (this.link.ahead("camera")) return;
    const camera = fromCamera(state.scene?.camera);
    if (!camera) return;
    this.camera = camera;
    this.turning = false;
    this.drawMarker();
  }

  orbit(dx: number, dy: number): void {
    this.move((c) => orbitByDrag(c, dx, dy));
  }

  pan(dx: number, dy: number, viewportHeight: number): void {
    this.move((c) => pan(c, dx, dy, viewportHeight));
  }

  zoom(factor: number): void {
    this.move((c) => zoom(c, factor));
  }

  /** A named view about the current target at the current distance: the server turns it, the state says where. */
  namedView(view: ViewName): void {
    const c = this.camera;
    if (!c || !this.link.driving || !this.link.state) return;
    this.home ??= c;
    this.turning = true;
    this.send({ view: NamedView[view], eye: vec3(c.eye), target: vec3(c.target), up: undefined, fovYDeg: c.fovYDeg });
  }

  /** Back to the camera before the first move (Home, Space). */
  goHome(): void {
    const home = this.home;
    if (!home || !this.camera) return;
    this.turning = false;
    this.move(() => home);
  }

  private move(step: (c: ViewCamera) => ViewCamera): void {
    if (!this.camera || this.turning || !this.link.driving || !this.link.state) return;
    this.home ??= this.camera;
    const c = this.camera = step(this.camera);
    this.drawMarker();
    this.onMoved();
    this.send({ view: NamedView.NAMED_VIEW_UNSPECIFIED, eye: vec3(c.eye), target: vec3(c.target), up: vec3(c.up),
                fovYDeg: c.fovYDeg });
  }

  /** The state's camera (aperture, focus, exposure kept) with these fields. */
  private send(fields: Pick<Camera, "view" | "eye" | "target" | "up" | "fovYDeg">): void {
    const current = this.link.state?.scene?.camera;
    if (!current) return;
    this.link.post({ case: "camera", value: Object.assign(create(CameraSchema, current), fields) });
  }

  /** The orientation marker: the patient's axes as the camera sees them, the nearer drawn last. */
  drawMarker(): void {
    const canvas = $<HTMLCanvasElement>("orientation"), g = canvas.getContext("2d");
    const placement = this.link.placement;
    if (!g || !this.camera || !placement) return;
    const half = canvas.width / 2, reach = half * 0.62;
    g.clearRect(0, 0, canvas.width, canvas.height);
    g.lineWidth = 2;
    g.font = "bold 13px system-ui, sans-serif";
    g.textAlign = "center";
    g.textBaseline = "middle";
    for (const a of markerAxes(this.camera, placement)) {
      const x = half + a.x * reach, y = half - a.y * reach;
      g.globalAlpha = a.depth < 0 ? 0.45 : 1;
      g.strokeStyle = g.fillStyle = MARKER_COLOURS[a.letter];
      g.beginPath();
      g.moveTo(half, half);
      g.lineTo(x, y);
      g.stroke();
      g.fillText(a.letter, half + a.x * (reach + 10), half - a.y * (reach + 10));
    }
    g.globalAlpha = 1;
  }
}

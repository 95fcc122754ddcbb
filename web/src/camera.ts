// Camera and key-light motion as the desktop viewer does it
// (client-cpp/viewer/camera_control.cpp): a turntable orbit about the target,
// zoom along the view, pan in the view plane, the key light turned about the
// target like the eye. World space is the session's volume-centred frame
// (mm), where the state's camera and lights are. Named views are the
// server's: the page asks for one with an event and shows what it answers.
import type { Camera } from "../gen/cinevol/v1/scene_pb.js";
import { add, cross, dot, len, norm, scale, sub, v3, type V3 } from "./vec.js";

export interface ViewCamera {
  eye: V3;
  target: V3;
  up: V3;
  fovYDeg: number;
}

/** A state's camera as numbers; undefined without an eye and a target (a server older than the page). */
export function fromCamera(c: Camera | undefined): ViewCamera | undefined {
  if (!c?.eye || !c.target) return undefined;
  return { eye: v3(c.eye.x, c.eye.y, c.eye.z), target: v3(c.target.x, c.target.y, c.target.z),
           up: c.up ? v3(c.up.x, c.up.y, c.up.z) : v3(0, 0, 1), fovYDeg: c.fovYDeg ?? 30 };
}

/** Degrees the eye turns per CSS pixel dragged (the desktop viewer's 0.4). */
export const DEGREES_PER_PIXEL = 0.4;

/** The zoom factor of a right-button drag of `dy` pixels (down: farther). */
export const dragZoomFactor = (dy: number): number => Math.exp(dy * 0.01);

/** The zoom factor of `steps` wheel steps (positive: closer; a step is 100 of a wheel event's deltaY). */
export const wheelZoomFactor = (steps: number): number => Math.pow(0.9, steps);

/** Rodrigues' rotation of v about the unit axis k. */
export function rotate(v: V3, k: V3, degrees: number): V3 {
  const a = (degrees * Math.PI) / 180, c = Math.cos(a), s = Math.sin(a);
  return add(add(scale(v, c), scale(cross(k, v), s)), scale(k, dot(k, v) * (1 - c)));
}

function right(c: ViewCamera): V3 {
  return norm(cross(sub(c.target, c.eye), c.up));
}

function screenUp(c: ViewCamera): V3 {
  return norm(cross(right(c), sub(c.target, c.eye)));
}

/** Turns the eye about the target: yaw about the screen's up, pitch about its right axis. */
export function orbit(c: ViewCamera, yawDeg: number, pitchDeg: number): ViewCamera {
  const r = right(c), up = screenUp(c);
  let offset = rotate(sub(c.eye, c.target), up, -yawDeg);
  const turnedRight = rotate(r, up, -yawDeg);
  offset = rotate(offset, turnedRight, -pitchDeg);
  const eye = add(c.target, offset);
  return { ...c, eye, up: norm(cross(turnedRight, sub(c.target, eye))) };
}

/** An orbit by a drag of (dx, dy) pixels: yaw and pitch of DEGREES_PER_PIXEL a pixel. */
export function orbitByDrag(c: ViewCamera, dx: number, dy: number): ViewCamera {
  return orbit(c, dx * DEGREES_PER_PIXEL, dy * DEGREES_PER_PIXEL);
}

/** Moves the eye towards the target (factor < 1: closer), never nearer than 1 mm. */
export function zoom(c: ViewCamera, factor: number): ViewCamera {
  if (!(factor > 0) || !Number.isFinite(factor)) return c;
  const offset = sub(c.eye, c.target), distance = len(offset);
  return { ...c, eye: add(c.target, scale(offset, Math.max(distance * factor, 1) / distance)) };
}

/** Moves eye and target in the view plane so the point under the cursor follows it. */
export function pan(c: ViewCamera, dx: number, dy: number, viewportHeight: number): ViewCamera {
  const distance = len(sub(c.eye, c.target));
  const mmPerPixel = (2 * distance * Math.tan((0.5 * c.fovYDeg * Math.PI) / 180)) / Math.max(1, viewportHeight);
  const shift = add(scale(right(c), -dx * mmPerPixel), scale(screenUp(c), dy * mmPerPixel));
  return { ...c, eye: add(c.eye, shift), target: add(c.target, shift) };
}

export interface AreaLightPose {
  center: V3;
  edgeU: V3;
  edgeV: V3;
}

/** Where a light sits as seen from the camera: azimuth (0 towards the eye, + to the right) and elevation. */
export function lightDirection(light: AreaLightPose, c: ViewCamera): { azimuthDeg: number; elevationDeg: number } {
  const r = right(c), up = screenUp(c), toEye = norm(sub(c.eye, c.target));
  const d = norm(sub(light.center, c.target));
  return {
    azimuthDeg: (Math.atan2(dot(d, r), dot(d, toEye)) * 180) / Math.PI,
    elevationDeg: (Math.asin(Math.min(1, Math.max(-1, dot(d, up)))) * 180) / Math.PI,
  };
}

/** Moves the light to that direction at the same distance from the target, still facing it. */
export function setLightDirection(light: AreaLightPose, c: ViewCamera, azimuthDeg: number,
                                  elevationDeg: number): AreaLightPose {
  const r = right(c), up = screenUp(c), toEye = norm(sub(c.eye, c.target));
  const offset = sub(light.center, c.target);
  const a = (azimuthDeg * Math.PI) / 180, e = (elevationDeg * Math.PI) / 180;
  const from = norm(offset);
  const to = add(scale(add(scale(toEye, Math.cos(a)), scale(r, Math.sin(a))), Math.cos(e)), scale(up, Math.sin(e)));
  const axis = cross(from, to), s = len(axis);
  if (!(s > 1e-6)) return { ...light, center: add(c.target, scale(to, len(offset))) };
  const degrees = (Math.atan2(s, dot(from, to)) * 180) / Math.PI, k = scale(axis, 1 / s);
  return {
    center: add(c.target, rotate(offset, k, degrees)),
    edgeU: rotate(light.edgeU, k, degrees),
    edgeV: rotate(light.edgeV, k, degrees),
  };
}

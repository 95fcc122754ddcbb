// Where things are on a slice and on the 3D view, and the measurements
// between picked points: pure functions the reading panes and the tests use.
// A slice is drawn in millimetres, as the desktop viewer draws it
// (client-cpp/viewer/reading_tools.cpp, ShownSlice): its image, crosshair,
// measurements, picks and edge letters all go through shownSlice and the two
// mappings below it.
import type { SliceImage } from "../gen/cinevol/v1/service_pb.js";
import type { ViewCamera } from "./camera.js";
import { fitted, fromFrame, toFrame, type FrameRect } from "./pointers.js";
import { add, cross, dot, len, norm, scale, sub, v3, type V3 } from "./vec.js";

const vec = (v: { x: number; y: number; z: number } | undefined): V3 => v ? v3(v.x, v.y, v.z) : v3(0, 0, 0);

/** The patient position (LPS mm) of a slice image's pixel (pixel centres at whole numbers). */
export function slicePixelToPatient(image: SliceImage, column: number, row: number): V3 {
  return add(vec(image.originMm), add(scale(vec(image.rowDirection), column * image.rowSpacingMm),
                                      scale(vec(image.columnDirection), row * image.columnSpacingMm)));
}

/** The slice pixel a patient position falls on, and how far it lies off the slice's plane (mm). */
export function patientToSlicePixel(image: SliceImage, p: V3): { column: number; row: number; offPlaneMm: number } {
  const d = sub(p, vec(image.originMm)), r = vec(image.rowDirection), c = vec(image.columnDirection);
  return { column: dot(d, r) / image.rowSpacingMm, row: dot(d, c) / image.columnSpacingMm,
           offPlaneMm: dot(d, norm(cross(r, c))) };
}

/** A slice image's size in mm: its pixels are rowSpacingMm wide and columnSpacingMm tall, not square. */
export function sliceSizeMm(image: SliceImage): { width: number; height: number } {
  return { width: image.width * image.rowSpacingMm, height: image.height * image.columnSpacingMm };
}

/**
 * Where a slice shows in a pane of `pane` CSS pixels: fitted whole and
 * centred in its true proportions, so a coronal reformat of 2 mm slices is
 * as tall as the anatomy, not as its count of pixels.
 */
export function shownSlice(pane: { width: number; height: number }, image: SliceImage): FrameRect {
  return fitted(pane, sliceSizeMm(image));
}

/** Where a patient position falls in the pane (CSS px from its top left), and how far off the slice's plane (mm). */
export function patientToPane(image: SliceImage, shown: FrameRect, p: V3): { x: number; y: number; offPlaneMm: number } {
  const q = patientToSlicePixel(image, p);
  // Pixel centres at whole numbers: a pixel's cell spans half a pixel either side.
  const at = fromFrame({ x: (q.column + 0.5) / image.width, y: (q.row + 0.5) / image.height }, shown);
  return { ...at, offPlaneMm: q.offPlaneMm };
}

/** The patient position under a point of the pane (CSS px from its top left); null off the slice. */
export function paneToPatient(image: SliceImage, shown: FrameRect, at: { x: number; y: number }): V3 | null {
  const f = toFrame(at, shown);
  return f && slicePixelToPatient(image, f.x * image.width - 0.5, f.y * image.height - 0.5);
}

export function distanceMm(a: V3, b: V3): number {
  return len(sub(a, b));
}

/** The angle at `vertex` between the rays to `a` and `b`, in degrees. */
export function angleDeg(a: V3, vertex: V3, b: V3): number {
  const u = norm(sub(a, vertex)), w = norm(sub(b, vertex));
  return (Math.acos(Math.min(1, Math.max(-1, dot(u, w)))) * 180) / Math.PI;
}

/** A measurement's value in words: "42.5 mm" or "37.0°". */
export function measurementText(points: V3[]): string {
  if (points.length === 2) return `${distanceMm(points[0], points[1]).toFixed(1)} mm`;
  if (points.length === 3) return `${angleDeg(points[0], points[1], points[2]).toFixed(1)}°`;
  return "";
}

/** Where a point of the camera's frame falls on a `width` x `height` view (pixels, y down); null behind the eye. */
export function projectToView(c: ViewCamera, p: V3, width: number, height: number): { x: number; y: number } | null {
  const forward = norm(sub(c.target, c.eye)), right = norm(cross(forward, c.up)), up = cross(right, forward);
  const d = sub(p, c.eye), depth = dot(d, forward);
  if (depth <= 1e-6) return null;
  const f = 1 / Math.tan((c.fovYDeg * Math.PI) / 360);
  return { x: width / 2 + (dot(d, right) / depth) * f * (height / 2), y: height / 2 - (dot(d, up) / depth) * f * (height / 2) };
}

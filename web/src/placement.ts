// Where the session's volume lies in the patient (SessionState.placement),
// and the one place that moves points and directions between the two
// frames: the volume-centred frame the camera and lights live in (index
// axes in mm, the box around the corner voxels' centres centred at the
// origin) and patient coordinates (LPS mm: clipping, measurements, slices,
// the crosshair):  p_lps = origin + D (v + (dims - 1) spacing / 2).
// The twin of the server's VolumePlacement (server/scene/scene_frame.h).
import type { VolumePlacement } from "../gen/cinevol/v1/service_pb.js";
import { add, scale, sub, v3, type V3 } from "./vec.js";

export type Axis = "x" | "y" | "z";
const AXES: readonly Axis[] = ["x", "y", "z"];

export interface Placement {
  /** D, row-major: column c is index axis c's direction in the patient (LPS). */
  readonly direction: readonly number[];
  readonly originMm: V3;   // LPS mm of voxel (0, 0, 0)'s centre
  readonly spacingMm: V3;
  readonly dims: V3;       // voxels along each index axis
}

export interface Box {
  min: V3;
  max: V3;
}

/** The state's placement; undefined where it has none (a state from a server older than the page). */
export function placementOf(p: VolumePlacement | undefined): Placement | undefined {
  if (!p || p.direction.length !== 9 || !p.originMm || !p.spacingMm || !p.dims) return undefined;
  const vec = (a: { x: number; y: number; z: number }) => v3(a.x, a.y, a.z);
  return { direction: [...p.direction], originMm: vec(p.originMm), spacingMm: vec(p.spacingMm), dims: vec(p.dims) };
}

/** Whether two placements put the volume in the same place (a new one moves the crosshair and the crop box). */
export function samePlacement(a: Placement | undefined, b: Placement | undefined): boolean {
  const numbers = (p: Placement) => [...p.direction, ...[p.originMm, p.spacingMm, p.dims].flatMap((q) => [q.x, q.y, q.z])];
  if (a === b) return true;
  if (a === undefined || b === undefined) return false;
  const x = numbers(a), y = numbers(b);
  return x.length === y.length && x.every((n, i) => n === y[i]);
}

/** D v: a direction of the volume-centred frame (index axes) in the patient. */
export function directionToPatient(p: Placement, v: V3): V3 {
  const d = p.direction;
  return v3(d[0] * v.x + d[1] * v.y + d[2] * v.z, d[3] * v.x + d[4] * v.y + d[5] * v.z,
            d[6] * v.x + d[7] * v.y + d[8] * v.z);
}

/** D^T lps: a patient direction in the volume-centred frame (D is orthonormal). */
export function directionToVolume(p: Placement, lps: V3): V3 {
  const d = p.direction;
  return v3(d[0] * lps.x + d[3] * lps.y + d[6] * lps.z, d[1] * lps.x + d[4] * lps.y + d[7] * lps.z,
            d[2] * lps.x + d[5] * lps.y + d[8] * lps.z);
}

/** Half the extent of the box around the corner voxels' centres, along the index axes (mm). */
function halfExtent(p: Placement): V3 {
  const { dims: n, spacingMm: s } = p;
  return v3(((n.x - 1) * s.x) / 2, ((n.y - 1) * s.y) / 2, ((n.z - 1) * s.z) / 2);
}

/** A point of the volume-centred frame in patient coordinates (LPS mm). */
export function toPatient(p: Placement, v: V3): V3 {
  return add(p.originMm, directionToPatient(p, add(v, halfExtent(p))));
}

/** A patient point (LPS mm) in the volume-centred frame: toPatient's inverse. */
export function toVolume(p: Placement, lps: V3): V3 {
  return sub(directionToVolume(p, sub(lps, p.originMm)), halfExtent(p));
}

/** The volume's centre in the patient: where the volume-centred frame's origin lies. */
export function centre(p: Placement): V3 {
  return toPatient(p, v3(0, 0, 0));
}

/** The eight corners of the box around the corner voxels' centres, in the patient; bit c of i: index axis c's far end. */
function patientCorners(p: Placement): V3[] {
  const half = halfExtent(p);
  return Array.from({ length: 8 }, (_, i) =>
    toPatient(p, v3((i & 1 ? 1 : -1) * half.x, (i & 2 ? 1 : -1) * half.y, (i & 4 ? 1 : -1) * half.z)));
}

/** The patient-axis-aligned box around the centres of the volume's corner voxels: what the crop sliders span. */
export function patientBox(p: Placement): Box {
  const corners = patientCorners(p);
  const bound = (pick: (...values: number[]) => number) =>
    v3(pick(...corners.map((c) => c.x)), pick(...corners.map((c) => c.y)), pick(...corners.map((c) => c.z)));
  return { min: bound(Math.min), max: bound(Math.max) };
}

/** A crop box from fractions [0, 1] of a patient box along L, P and S (lo < hi on each). */
export function cropFromFractions(box: Box, lo: V3, hi: V3): { center: V3; size: V3 } {
  const at = (axis: Axis, f: number) => box.min[axis] + f * (box.max[axis] - box.min[axis]);
  const a = AXES.map((k) => at(k, lo[k])), b = AXES.map((k) => at(k, hi[k]));
  const size = AXES.map((_, i) => Math.max(1e-3, b[i] - a[i]));
  return { center: scale(v3(a[0] + b[0], a[1] + b[1], a[2] + b[2]), 0.5), size: v3(size[0], size[1], size[2]) };
}

/** The volume's spacing along a patient axis: that of the index axis most along it (one voxel across a slice). */
export function spacingAlong(p: Placement, axis: Axis): number {
  const along = directionToVolume(p, v3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0));
  const column = AXES.reduce((best, c) => Math.abs(along[c]) > Math.abs(along[best]) ? c : best, "x" as Axis);
  return p.spacingMm[column];
}

/**
 * Where the plane at `position` mm along patient axis `axis` cuts the
 * volume's box (its corner voxels' centres, as the slices span it): the
 * polygon's corners in order around it, LPS mm; empty where it misses.
 */
export function slicePlaneOutline(p: Placement, axis: Axis, position: number): V3[] {
  const corners = patientCorners(p), points: V3[] = [];
  for (let a = 0; a < 8; ++a) {
    for (const bit of [1, 2, 4]) {
      if (a & bit) continue;  // each of the 12 edges once, from its lower corner
      const from = corners[a], to = corners[a | bit];
      const da = from[axis] - position, db = to[axis] - position;
      if (da * db > 0 || da === db) continue;
      points.push(add(from, scale(sub(to, from), da / (da - db))));
    }
  }
  if (points.length < 3) return [];
  // In order around their centre, in the plane's own two axes.
  const [u, w] = AXES.filter((k) => k !== axis);
  const cu = points.reduce((sum, q) => sum + q[u], 0) / points.length;
  const cw = points.reduce((sum, q) => sum + q[w], 0) / points.length;
  return points.sort((q, r) => Math.atan2(q[w] - cw, q[u] - cu) - Math.atan2(r[w] - cw, r[u] - cu));
}

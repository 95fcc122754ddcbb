// Where a volume lies in patient space (LPS, mm), from VolumeInfo's
// origin, spacing and direction cosines: what the crop sliders span.
import type { VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import { v3, type V3 } from "./vec.js";

export interface Box {
  min: V3;
  max: V3;
}

/** The patient-axis-aligned box around the centres of the volume's corner voxels. */
export function patientBox(volume: VolumeInfo): Box {
  const d = volume.direction.length === 9 ? volume.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const o = volume.originMm ?? v3(0, 0, 0), s = volume.spacingMm ?? v3(1, 1, 1), n = volume.dims ?? v3(1, 1, 1);
  const extent = [(n.x - 1) * s.x, (n.y - 1) * s.y, (n.z - 1) * s.z];
  const min = [o.x, o.y, o.z], max = [o.x, o.y, o.z];
  for (let corner = 0; corner < 8; ++corner) {
    const index = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1].map((bit, c) => bit * extent[c]);
    for (let r = 0; r < 3; ++r) {
      const p = [o.x, o.y, o.z][r] + d[3 * r] * index[0] + d[3 * r + 1] * index[1] + d[3 * r + 2] * index[2];
      min[r] = Math.min(min[r], p);
      max[r] = Math.max(max[r], p);
    }
  }
  return { min: v3(min[0], min[1], min[2]), max: v3(max[0], max[1], max[2]) };
}

/** A crop box from fractions [0, 1] of the patient box along L, P and S (lo < hi on each). */
export function cropFromFractions(box: Box, lo: V3, hi: V3): { center: V3; size: V3 } {
  const at = (axis: "x" | "y" | "z", f: number) => box.min[axis] + f * (box.max[axis] - box.min[axis]);
  const axes = ["x", "y", "z"] as const;
  const a = axes.map((k) => at(k, lo[k])), b = axes.map((k) => at(k, hi[k]));
  const size = axes.map((_, i) => Math.max(1e-3, b[i] - a[i]));
  return { center: v3((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2), size: v3(size[0], size[1], size[2]) };
}

/**
 * A camera-frame point in patient space. Scenes in PATIENT_LPS are there
 * already; the volume-centred frame is index axes scaled to mm with the
 * volume's centre at the origin.
 */
export function toPatient(volume: VolumeInfo, patientFrame: boolean, p: V3, isDirection = false): V3 {
  if (patientFrame) return p;
  const d = volume.direction.length === 9 ? volume.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const turn = (v: V3) => v3(d[0] * v.x + d[1] * v.y + d[2] * v.z, d[3] * v.x + d[4] * v.y + d[5] * v.z,
                             d[6] * v.x + d[7] * v.y + d[8] * v.z);
  if (isDirection) return turn(p);
  const s = volume.spacingMm ?? v3(1, 1, 1), n = volume.dims ?? v3(1, 1, 1), o = volume.originMm ?? v3(0, 0, 0);
  const half = turn(v3(((n.x - 1) * s.x) / 2, ((n.y - 1) * s.y) / 2, ((n.z - 1) * s.z) / 2));
  const q = turn(p);
  return v3(o.x + half.x + q.x, o.y + half.y + q.y, o.z + half.z + q.z);
}

/** The inverse of toPatient: a patient point in the camera's frame. */
export function fromPatient(volume: VolumeInfo, patientFrame: boolean, p: V3): V3 {
  if (patientFrame) return p;
  const d = volume.direction.length === 9 ? volume.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const centre = toPatient(volume, false, v3(0, 0, 0));
  const q = v3(p.x - centre.x, p.y - centre.y, p.z - centre.z);
  return v3(d[0] * q.x + d[3] * q.y + d[6] * q.z, d[1] * q.x + d[4] * q.y + d[7] * q.z, d[2] * q.x + d[5] * q.y + d[8] * q.z);
}

/** The volume's spacing along a patient axis: that of the index axis most along it. */
export function spacingAlong(volume: VolumeInfo, axis: "x" | "y" | "z"): number {
  const d = volume.direction.length === 9 ? volume.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const r = { x: 0, y: 1, z: 2 }[axis], s = volume.spacingMm ?? v3(1, 1, 1);
  const column = [0, 1, 2].reduce((best, c) => Math.abs(d[3 * r + c]) > Math.abs(d[3 * r + best]) ? c : best, 0);
  return [s.x, s.y, s.z][column];
}

/**
 * Where the plane at `position` mm along patient axis `axis` cuts the volume's
 * box (its corner voxels' centres, as the slices span it): the polygon's
 * corners in order around it, LPS mm; empty where the plane misses the box.
 */
export function slicePlaneOutline(volume: VolumeInfo, axis: "x" | "y" | "z", position: number): V3[] {
  const d = volume.direction.length === 9 ? volume.direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const o = volume.originMm ?? v3(0, 0, 0), s = volume.spacingMm ?? v3(1, 1, 1), n = volume.dims ?? v3(1, 1, 1);
  const extent = [(n.x - 1) * s.x, (n.y - 1) * s.y, (n.z - 1) * s.z];
  const corner = (bits: number): V3 => {
    const i = [bits & 1, (bits >> 1) & 1, (bits >> 2) & 1].map((bit, c) => bit * extent[c]);
    const at = (r: number) => d[3 * r] * i[0] + d[3 * r + 1] * i[1] + d[3 * r + 2] * i[2];
    return v3(o.x + at(0), o.y + at(1), o.z + at(2));
  };
  const points: V3[] = [];
  for (let a = 0; a < 8; ++a) {
    for (const bit of [1, 2, 4]) {
      if (a & bit) continue;  // each of the 12 edges once, from its lower corner
      const p = corner(a), q = corner(a | bit);
      const da = p[axis] - position, db = q[axis] - position;
      if (da * db > 0 || da === db) continue;
      const t = da / (da - db);
      points.push(v3(p.x + t * (q.x - p.x), p.y + t * (q.y - p.y), p.z + t * (q.z - p.z)));
    }
  }
  if (points.length < 3) return [];
  // In order around their centre, in the plane's own two axes.
  const [u, w] = (["x", "y", "z"] as const).filter((k) => k !== axis);
  const cu = points.reduce((sum, p) => sum + p[u], 0) / points.length;
  const cw = points.reduce((sum, p) => sum + p[w], 0) / points.length;
  return points.sort((p, q) => Math.atan2(p[w] - cw, p[u] - cu) - Math.atan2(q[w] - cw, q[u] - cu));
}

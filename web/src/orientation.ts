// The orientation marker on the 3D view: the patient's axes (L, P, S and
// their opposites R, A, I) as the camera sees them, from the volume's
// direction cosines.
import { cross, dot, norm, sub, v3, type V3 } from "./vec.js";
import type { ViewCamera } from "./camera.js";

export interface MarkerAxis {
  letter: string;  // the letter at the end pointing this way
  x: number;       // screen right, in [-1, 1]
  y: number;       // screen up
  depth: number;   // towards the viewer > 0
}

const AXES: [V3, string, string][] = [[v3(1, 0, 0), "L", "R"], [v3(0, 1, 0), "P", "A"], [v3(0, 0, 1), "S", "I"]];

/**
 * The six half-axes' screen directions, farthest first (so nearer ones draw
 * on top). `direction`: the volume's cosines (row-major, LPS); `patientFrame`:
 * the camera is in patient coordinates, else in the volume-centred frame.
 */
export function markerAxes(camera: ViewCamera, direction: readonly number[], patientFrame: boolean): MarkerAxis[] {
  const d = direction.length === 9 && !patientFrame ? direction : [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const toWorld = (p: V3) => v3(d[0] * p.x + d[3] * p.y + d[6] * p.z, d[1] * p.x + d[4] * p.y + d[7] * p.z,
                                d[2] * p.x + d[5] * p.y + d[8] * p.z);
  const forward = norm(sub(camera.target, camera.eye));
  const right = norm(cross(forward, camera.up)), up = cross(right, forward);
  const axes: MarkerAxis[] = [];
  for (const [axis, plus, minus] of AXES) {
    const w = toWorld(axis);
    const screen = { x: dot(w, right), y: dot(w, up), depth: -dot(w, forward) };
    axes.push({ letter: plus, ...screen }, { letter: minus, x: -screen.x, y: -screen.y, depth: -screen.depth });
  }
  return axes.sort((a, b) => a.depth - b.depth);
}

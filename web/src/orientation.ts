// The orientation marker on the 3D view: the patient's axes (L, P, S and
// their opposites R, A, I) as the camera sees them. The twin of the desktop
// viewer's MarkerAxes (client-cpp/viewer/reading_view.cpp).
import { cross, dot, norm, sub, v3, type V3 } from "./vec.js";
import type { ViewCamera } from "./camera.js";
import { directionToVolume, type Placement } from "./placement.js";

export interface MarkerAxis {
  letter: string;  // the letter at the end pointing this way
  x: number;       // screen right, in [-1, 1]
  y: number;       // screen up
  depth: number;   // towards the viewer > 0
}

const AXES: [V3, string, string][] = [[v3(1, 0, 0), "L", "R"], [v3(0, 1, 0), "P", "A"], [v3(0, 0, 1), "S", "I"]];

/**
 * The six half-axes' screen directions as `camera` (the volume-centred
 * frame, as the state's) sees them, farthest first (so nearer ones draw on
 * top).
 */
export function markerAxes(camera: ViewCamera, placement: Placement): MarkerAxis[] {
  const forward = norm(sub(camera.target, camera.eye));
  const right = norm(cross(forward, camera.up)), up = cross(right, forward);
  const axes: MarkerAxis[] = [];
  for (const [axis, plus, minus] of AXES) {
    const w = directionToVolume(placement, axis);
    const screen = { x: dot(w, right), y: dot(w, up), depth: -dot(w, forward) };
    axes.push({ letter: plus, ...screen }, { letter: minus, x: -screen.x, y: -screen.y, depth: -screen.depth });
  }
  return axes.sort((a, b) => a.depth - b.depth);
}

// A volume of known shape for the end-to-end test: a sphere in voxels that
// are not cubes, written as NRRD; and how wide and tall it is drawn, and
// where the crosshair crosses, read off a screenshot.
import { writeFileSync } from "node:fs";
import type { decodePng } from "./png.js";

type Png = ReturnType<typeof decodePng>;
type Triple = [number, number, number];

/**
 * A sphere of `radiusMm` at the centre of `dims` voxels of `spacingMm`, LPS,
 * origin 0. Its values fall linearly with the distance from the centre, 35 a
 * mm, through 50 at the radius: the soft-tissue window (350 wide about 50)
 * turns that into grey rising linearly over the 10 mm about the surface, so
 * however a browser interpolates the pixels, its mid-grey lies on the
 * surface, whether a pixel is 0.8 or 2 mm.
 */
export function writeSphereNrrd(path: string, dims: Triple, spacingMm: Triple, radiusMm: number): void {
  const [nx, ny, nz] = dims, [sx, sy, sz] = spacingMm;
  const centre = [(nx - 1) * sx / 2, (ny - 1) * sy / 2, (nz - 1) * sz / 2];
  const values = Buffer.alloc(2 * nx * ny * nz);
  for (let k = 0, at = 0; k < nz; ++k) {
    for (let j = 0; j < ny; ++j) {
      for (let i = 0; i < nx; ++i, at += 2) {
        const r = Math.hypot(i * sx - centre[0], j * sy - centre[1], k * sz - centre[2]);
        values.writeInt16LE(Math.round(Math.max(-1000, Math.min(1100, 50 + (radiusMm - r) * 35))), at);
      }
    }
  }
  const header = ["NRRD0004", "type: short", "dimension: 3", `sizes: ${nx} ${ny} ${nz}`,
    "space: left-posterior-superior", `space directions: (${sx},0,0) (0,${sy},0) (0,0,${sz})`, "space origin: (0,0,0)",
    "encoding: raw", "endian: little", "", ""].join("\n");
  writeFileSync(path, Buffer.concat([Buffer.from(header, "latin1"), values]));
}

/** How white a pixel is: its least channel, the grey of a grey pixel; a coloured frame or line counts as dark. */
const whiteness = (png: Png, x: number, y: number) => {
  const i = (y * png.width + x) * png.channels;
  return Math.min(png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]);
};

/** Where a run of values first rises through `threshold`, between samples (index units); NaN where it never does. */
function rising(values: number[], threshold: number): number {
  for (let i = 1; i < values.length; ++i) {
    if (values[i - 1] <= threshold && values[i] > threshold) return i - 1 + (threshold - values[i - 1]) / (values[i] - values[i - 1]);
  }
  return NaN;
}

/**
 * The white disc on a screenshot: its centre and its width and height
 * where the grey crosses `threshold`, through the centre, to a fraction of
 * a pixel (screenshot pixels: CSS pixels at a device pixel ratio of 1; a
 * pixel's centre at its index + 0.5).
 */
export function discOn(png: Png, threshold = 127.5): { x: number; y: number; width: number; height: number } {
  let left = png.width, right = -1, top = png.height, bottom = -1;
  for (let y = 0; y < png.height; ++y) {
    for (let x = 0; x < png.width; ++x) {
      if (whiteness(png, x, y) <= threshold) continue;
      left = Math.min(left, x); right = Math.max(right, x); top = Math.min(top, y); bottom = Math.max(bottom, y);
    }
  }
  if (right < 0) throw new Error("no bright disc on the screenshot");
  const cx = Math.round((left + right) / 2), cy = Math.round((top + bottom) / 2);
  const row = Array.from({ length: png.width }, (_, x) => whiteness(png, x, cy));
  const column = Array.from({ length: png.height }, (_, y) => whiteness(png, cx, y));
  const edges = (run: number[]) => [rising(run, threshold), run.length - 1 - rising([...run].reverse(), threshold)];
  const [x0, x1] = edges(row), [y0, y1] = edges(column);
  return { x: (x0 + x1) / 2 + 0.5, y: (y0 + y1) / 2 + 0.5, width: x1 - x0, height: y1 - y0 };
}

/**
 * Where the crosshair's vertical and horizontal lines run (yellow: red and
 * green far above blue), in CSS pixels; the outer pixels left out, where the
 * pane's frame (yellow for the sagittal slice) runs along an image that
 * reaches the pane's edge.
 */
export function crosshairOn(png: Png, frame = 3): { x: number; y: number } {
  const columns = new Array<number>(png.width).fill(0), rows = new Array<number>(png.height).fill(0);
  for (let y = frame; y < png.height - frame; ++y) {
    for (let x = frame; x < png.width - frame; ++x) {
      const i = (y * png.width + x) * png.channels, [r, g, b] = [png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]];
      if (r - b > 90 && g - b > 70) columns[x] += 1, rows[y] += 1;
    }
  }
  const most = (counts: number[]) => counts.indexOf(Math.max(...counts));
  return { x: most(columns) + 0.5, y: most(rows) + 0.5 };
}

/**
 * A time series (issue 59) as a 4-D NRRD: a ball of 1000 in 0, `radiusMm` in 1 mm voxels, that moves 3 voxels
 * along x a phase, `secondsApart` between phases (the NRRD's fourth spacing).
 */
export function writeMovingBallNrrd(path: string, size: number, phases: number, radiusMm: number,
                                    secondsApart: number): void {
  const values = Buffer.alloc(2 * size * size * size * phases);
  for (let t = 0, at = 0; t < phases; ++t) {
    for (let k = 0; k < size; ++k) {
      for (let j = 0; j < size; ++j) {
        for (let i = 0; i < size; ++i, at += 2) {
          const r = Math.hypot(i - size / 4 - 3 * t, j - size / 2, k - size / 2);
          values.writeInt16LE(r <= radiusMm ? 1000 : 0, at);
        }
      }
    }
  }
  const header = ["NRRD0004", "type: short", "dimension: 4", `sizes: ${size} ${size} ${size} ${phases}`,
    `spacings: 1 1 1 ${secondsApart}`, "kinds: domain domain domain time", "encoding: raw", "endian: little", "", ""]
    .join("\n");
  writeFileSync(path, Buffer.concat([Buffer.from(header, "latin1"), values]));
}

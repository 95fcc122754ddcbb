// The page's view math against tests/golden/view_math.json, the cases the
// desktop viewer's twins meet too (tests/client/view_math_test.cpp): the
// camera under the mouse, projection, slice geometry, the orientation
// marker and its edge letters, measurements and the patient frame. A case
// the page computes otherwise, or a kind it does not know, fails.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { join } from "node:path";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { SliceImageSchema } from "../gen/cinevol/v1/service_pb.js";
import { dragZoomFactor, orbitByDrag, pan, wheelZoomFactor, zoom, type ViewCamera } from "../src/camera.js";
import { angleDeg, distanceMm, patientToSlicePixel, projectToView, slicePixelToPatient } from "../src/measure.js";
import { markerAxes, type MarkerAxis } from "../src/orientation.js";
import {
  directionToPatient, directionToVolume, slicePlaneOutline, spacingAlong, toPatient, toVolume, type Axis, type Placement,
} from "../src/placement.js";
import { v3, type V3 } from "../src/vec.js";

declare const CINEVOL_SOURCE_DIR: string;  // the checkout the tests were built from (build.mjs defines it)
const GOLDEN = process.env.CINEVOL_GOLDEN ?? join(CINEVOL_SOURCE_DIR, "tests", "golden", "view_math.json");

type Json = number | string | boolean | null | Json[] | { [key: string]: Json };
type Case = { name: string; kind: string; expected: { [key: string]: Json }; [key: string]: Json };
const golden = JSON.parse(readFileSync(GOLDEN, "utf8")) as { tolerance: number; [category: string]: Json };
const tolerance = golden.tolerance;
const CATEGORIES = ["camera", "slice_geometry", "edge_letters", "measurement", "patient_frame"];

const vec = (a: Json): V3 => {
  const [x, y, z] = a as number[];
  return v3(x, y, z);
};
const list = (p: V3): number[] => [p.x, p.y, p.z];
const cameraOf = (c: Json): ViewCamera => {
  const o = c as { [key: string]: Json };
  return { eye: vec(o.eye), target: vec(o.target), up: vec(o.up), fovYDeg: o.fov_y_deg as number };
};
const cameraJson = (c: ViewCamera) => ({ eye: list(c.eye), target: list(c.target), up: list(c.up), fov_y_deg: c.fovYDeg });
const placementOf = (p: Json): Placement => {
  const o = p as { [key: string]: Json };
  return { direction: o.direction as number[], originMm: vec(o.origin_mm), spacingMm: vec(o.spacing_mm), dims: vec(o.dims) };
};
const sliceOf = (s: Json) => {
  const o = s as { [key: string]: Json };
  const pb = (a: Json) => ({ x: vec(a).x, y: vec(a).y, z: vec(a).z });
  return create(SliceImageSchema, {
    originMm: pb(o.origin_mm), rowDirection: pb(o.row_direction), columnDirection: pb(o.column_direction),
    rowSpacingMm: o.row_spacing_mm as number, columnSpacingMm: o.column_spacing_mm as number,
    width: o.width as number, height: o.height as number,
  });
};

/** The letters at a view's edges: the half-axis pointing most to each side (as the viewer's test reads the marker). */
function edgesOf(axes: MarkerAxis[]) {
  const most = (key: (a: MarkerAxis) => number) => axes.reduce((best, a) => key(a) > key(best) ? a : best).letter;
  return { left: most((a) => -a.x), right: most((a) => a.x), top: most((a) => a.y), bottom: most((a) => -a.y) };
}

/** What the page makes of a case's inputs, in the shape of its `expected`. */
function compute(c: Case): { [key: string]: Json } {
  const camera = () => cameraOf(c.camera), placement = () => placementOf(c.placement);
  switch (c.kind) {
    case "orbit_drag": return { camera: cameraJson(orbitByDrag(camera(), c.dx_px as number, c.dy_px as number)) };
    case "pan_drag":
      return { camera: cameraJson(pan(camera(), c.dx_px as number, c.dy_px as number, c.viewport_height_px as number)) };
    case "zoom_drag": return { camera: cameraJson(zoom(camera(), dragZoomFactor(c.dy_px as number))) };
    case "wheel": return { camera: cameraJson(zoom(camera(), wheelZoomFactor(c.steps as number))) };
    case "project": {
      const at = projectToView(camera(), vec(c.point), c.width_px as number, c.height_px as number);
      return at ? { visible: true, x: at.x, y: at.y } : { visible: false };
    }
    case "slice_plane_outline":
      return { polygon: slicePlaneOutline(placement(), c.axis as Axis, c.position_mm as number).map(list) };
    case "voxel_step": return { mm: spacingAlong(placement(), c.axis as Axis) };
    case "slice_pixel_to_patient":
      return { lps: list(slicePixelToPatient(sliceOf(c.slice), c.column as number, c.row as number)) };
    case "patient_to_slice_pixel": {
      const p = patientToSlicePixel(sliceOf(c.slice), vec(c.lps));
      return { column: p.column, row: p.row, off_plane_mm: p.offPlaneMm };
    }
    case "marker_axes": {
      const axes = markerAxes(camera(), placement());
      return { axes: axes.map((a) => ({ letter: a.letter, x: a.x, y: a.y, depth: a.depth })), edges: edgesOf(axes) };
    }
    case "distance": {
      const [a, b] = (c.points as Json[]).map(vec);
      return { mm: distanceMm(a, b) };
    }
    case "angle": {
      const [a, vertex, b] = (c.points as Json[]).map(vec);
      return { deg: angleDeg(a, vertex, b) };
    }
    case "to_patient": return { point: list(toPatient(placement(), vec(c.point))) };
    case "to_volume": return { point: list(toVolume(placement(), vec(c.point))) };
    case "direction_to_patient": return { point: list(directionToPatient(placement(), vec(c.point))) };
    case "direction_to_volume": return { point: list(directionToVolume(placement(), vec(c.point))) };
    default: throw new Error(`a kind of case the page does not know: ${c.kind}`);
  }
}

/** Every field of `want` in `got`, numbers within the tolerance; `got` may say no more than `want`. */
function expectSame(want: Json, got: Json, where: string): void {
  if (typeof want === "number") {
    assert.equal(typeof got, "number", `${where}: ${JSON.stringify(got)}, not a number`);
    assert.ok(Math.abs((got as number) - want) <= tolerance, `${where}: ${got}, not ${want}`);
  } else if (Array.isArray(want)) {
    assert.ok(Array.isArray(got) && got.length === want.length, `${where}: ${JSON.stringify(got)}, not ${JSON.stringify(want)}`);
    want.forEach((w, i) => expectSame(w, (got as Json[])[i], `${where}[${i}]`));
  } else if (want !== null && typeof want === "object") {
    assert.ok(got !== null && typeof got === "object" && !Array.isArray(got), `${where}: ${JSON.stringify(got)}`);
    const g = got as { [key: string]: Json };
    assert.deepEqual(Object.keys(g).sort(), Object.keys(want).sort(), `${where}: the fields`);
    for (const key of Object.keys(want)) expectSame(want[key], g[key], `${where}.${key}`);
  } else {
    assert.equal(got, want, where);
  }
}

/** A polygon's corners may start anywhere and run either way round. */
function expectSamePolygon(want: Json, got: Json, where: string): void {
  const w = want as number[][], g = got as number[][], n = w.length;
  assert.equal(g.length, n, `${where}: ${g.length} corners, not ${n}`);
  const close = (a: number[], b: number[]) => a.every((v, i) => Math.abs(v - b[i]) <= tolerance);
  for (let start = 0; start < n; ++start) {
    for (const way of [1, -1]) {
      if (w.every((corner, i) => close(corner, g[(((start + way * i) % n) + n) % n]))) return;
    }
  }
  if (n > 0) assert.fail(`${where}: the corners ${JSON.stringify(g)} are not the polygon ${JSON.stringify(w)}`);
}

/** The six half-axes compared by letter, listed farthest first; the edges' letters as they are. */
function expectSameMarker(want: { [key: string]: Json }, got: { [key: string]: Json }, where: string): void {
  const axes = got.axes as { letter: string; depth: number }[];
  axes.forEach((a, i) => assert.ok(i === 0 || a.depth >= axes[i - 1].depth - tolerance, `${where}: not farthest first`));
  assert.equal(new Set(axes.map((a) => a.letter)).size, 6, `${where}: six letters`);
  for (const axis of want.axes as { letter: string }[]) {
    expectSame(axis, axes.find((a) => a.letter === axis.letter) ?? null, `${where}.${axis.letter}`);
  }
  expectSame(want.edges, got.edges, `${where}.edges`);
}

test("the golden file holds every category, each with cases", () => {
  assert.ok(tolerance > 0 && tolerance < 1e-3, `tolerance ${tolerance}`);
  for (const category of CATEGORIES) assert.ok((golden[category] as Json[] | undefined)?.length, category);
  assert.deepEqual(Object.keys(golden).filter((k) => k !== "about" && k !== "tolerance").sort(), [...CATEGORIES].sort(),
                   "a category this test does not read");
});

for (const category of CATEGORIES) {
  for (const c of (golden[category] ?? []) as Case[]) {
    test(`${category}: ${c.name}`, () => {
      const got = compute(c), where = `${category} "${c.name}"`;
      if (c.kind === "slice_plane_outline") expectSamePolygon(c.expected.polygon, got.polygon, where);
      else if (c.kind === "marker_axes") expectSameMarker(c.expected, got, where);
      else expectSame(c.expected, got, where);
    });
  }
}

import assert from "node:assert/strict";
import { test } from "node:test";
import { lightDirection, orbit, pan, setLightDirection, zoom, type ViewCamera } from "../src/camera.js";
import { len, sub, v3, type V3 } from "../src/vec.js";

const start: ViewCamera = { eye: v3(0, -500, 0), target: v3(0, 0, 0), up: v3(0, 0, 1), fovYDeg: 30 };
const near = (a: V3, b: V3, eps = 1e-6) => assert.ok(len(sub(a, b)) < eps, `${JSON.stringify(a)} vs ${JSON.stringify(b)}`);

test("four quarter turns of orbit come back to the start, at the same distance", () => {
  let c = start;
  for (let i = 0; i < 4; ++i) {
    c = orbit(c, 90, 0);
    assert.ok(Math.abs(len(sub(c.eye, c.target)) - 500) < 1e-6);
  }
  near(c.eye, start.eye, 1e-3);
});

test("a quarter yaw to the right looks from the viewer's left side (as the desktop viewer)", () => {
  const c = orbit(start, 90, 0);
  near(c.eye, v3(-500, 0, 0), 1e-3);
  near(c.up, v3(0, 0, 1), 1e-6);
});

test("pitch over the pole keeps up perpendicular to the view", () => {
  const c = orbit(start, 0, 120);
  const view = sub(c.target, c.eye);
  assert.ok(Math.abs(view.x * c.up.x + view.y * c.up.y + view.z * c.up.z) < 1e-6);
});

test("zoom never reaches the target, and ignores factors that are not positive numbers", () => {
  assert.ok(len(sub(zoom(start, 1e-9).eye, start.target)) >= 1);
  assert.deepEqual(zoom(start, NaN), start);
  assert.deepEqual(zoom(start, -2), start);
  assert.ok(Math.abs(len(sub(zoom(start, 0.5).eye, start.target)) - 250) < 1e-9);
});

test("pan moves eye and target together by the pixel's size at the target", () => {
  const c = pan(start, 100, 0, 1000);
  const mmPerPixel = (2 * 500 * Math.tan((15 * Math.PI) / 180)) / 1000;
  near(sub(c.eye, c.target), sub(start.eye, start.target));
  assert.ok(Math.abs(len(c.target) - 100 * mmPerPixel) < 1e-9);
});

test("setting the key light's direction reads back as the same direction", () => {
  const light = { center: v3(0, -300, 200), edgeU: v3(50, 0, 0), edgeV: v3(0, 0, 50) };
  const turned = setLightDirection(light, start, 40, 25);
  const d = lightDirection(turned, start);
  assert.ok(Math.abs(d.azimuthDeg - 40) < 1e-6 && Math.abs(d.elevationDeg - 25) < 1e-6);
  assert.ok(Math.abs(len(sub(turned.center, start.target)) - len(light.center)) < 1e-9);
});

test("the orientation marker: seen from the front, the patient's left is on the viewer's right and S is up", async () => {
  const { markerAxes } = await import("../src/orientation.js");
  const place = (direction: number[]) => ({ direction, originMm: v3(0, 0, 0), spacingMm: v3(1, 1, 1), dims: v3(9, 9, 9) });
  const axes = Object.fromEntries(markerAxes(start, place([1, 0, 0, 0, 1, 0, 0, 0, 1])).map((a) => [a.letter, a]));
  assert.ok(axes.L.x > 0.99 && axes.R.x < -0.99, "L on the right (anterior view, radiological habit)");
  assert.ok(axes.S.y > 0.99 && axes.I.y < -0.99);
  assert.ok(axes.A.depth > 0.99, "anterior points at the viewer");
  // A volume stored flipped in x (RAS-like columns): the marker still follows the patient.
  const flipped = Object.fromEntries(markerAxes({ ...start }, place([-1, 0, 0, 0, 1, 0, 0, 0, 1])).map((a) => [a.letter, a]));
  assert.ok(flipped.L.x < -0.99, "in the volume frame the same camera now sees the patient's left on its left");
});

// Slices drawn in millimetres (issue 55): the image's rectangle in a pane,
// and the one mapping between the pane and the patient that the crosshair,
// measurements, picks and edge letters share.
import assert from "node:assert/strict";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { SliceImageSchema } from "../gen/cinevol/v1/service_pb.js";
import { distanceMm, paneToPatient, patientToPane, shownSlice, sliceSizeMm } from "../src/measure.js";

const near = (a: number, b: number, what: string, tolerance = 1e-9) =>
  assert.ok(Math.abs(a - b) <= tolerance, `${what}: ${a}, not ${b}`);

// A coronal slice of a volume of 0.8 x 0.8 x 2 mm voxels, 72 x 72 x 32 of them: 72 pixels along +L (0.8 mm each),
// 32 down +I (2 mm each), the top-left pixel's centre at L 0, P 28.4, S 62.
const coronal = create(SliceImageSchema, {
  width: 72, height: 32, rowSpacingMm: 0.8, columnSpacingMm: 2, originMm: { x: 0, y: 28.4, z: 62 },
  rowDirection: { x: 1, y: 0, z: 0 }, columnDirection: { x: 0, y: 0, z: -1 }, edgeLetters: ["R", "L", "S", "I"],
});

test("a slice shows in its millimetre proportions, not its pixels'", () => {
  assert.deepEqual(sliceSizeMm(coronal), { width: 57.6, height: 64 });
  const shown = shownSlice({ width: 400, height: 400 }, coronal);
  near(shown.width / shown.height, 57.6 / 64, "the rectangle's aspect is the anatomy's");
  near(shown.height, 400, "as tall as the pane");
  near(shown.left, (400 - shown.width) / 2, "centred");
  // 72 x 32 square pixels would have been 2.25 times wider than tall: the MR head squashed, the chest stretched.
  assert.ok(shown.width < shown.height);
});

test("a patient position and its place in the pane map both ways, pixel cells edge to edge", () => {
  const shown = shownSlice({ width: 300, height: 500 }, coronal);
  const topLeftCorner = patientToPane(coronal, shown, { x: -0.4, y: 28.4, z: 63 });  // the top-left pixel's outer corner
  near(topLeftCorner.x, shown.left, "left edge", 1e-6);
  near(topLeftCorner.y, shown.top, "top edge", 1e-6);
  const p = { x: 21.2, y: 28.4, z: 17 };
  const at = patientToPane(coronal, shown, p);
  near(at.offPlaneMm, 0, "in the plane");
  const back = paneToPatient(coronal, shown, at)!;
  near(distanceMm(back, p), 0, "round trip", 1e-6);
  assert.equal(paneToPatient(coronal, shown, { x: shown.left - 1, y: shown.top + 5 }), null, "off the image: no pick");
  near(patientToPane(coronal, shown, { x: 0, y: 31.4, z: 62 }).offPlaneMm, 3, "3 mm posterior of the plane", 1e-6);
});

test("a sphere is as wide as it is tall on screen, and a measurement across it reads its diameter", () => {
  const shown = shownSlice({ width: 439, height: 399 }, coronal);
  const centre = { x: 28.4, y: 28.4, z: 31 };
  const onScreen = (dx: number, dz: number) => patientToPane(coronal, shown, { x: centre.x + dx, y: centre.y, z: centre.z + dz });
  const width = onScreen(20, 0).x - onScreen(-20, 0).x, height = onScreen(0, -20).y - onScreen(0, 20).y;
  near(width, height, "40 mm across and 40 mm down take as many screen pixels", 1e-6);
  // Clicks at its drawn top and bottom are picks 40 mm apart.
  const top = paneToPatient(coronal, shown, onScreen(0, 20))!, bottom = paneToPatient(coronal, shown, onScreen(0, -20))!;
  near(distanceMm(top, bottom), 40, "the diameter", 1e-6);
});

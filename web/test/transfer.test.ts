import assert from "node:assert/strict";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { TransferFunctionSchema } from "../gen/cinevol/v1/scene_pb.js";
import { addPoint, applyWindowLevel, deletePoint, movePoint, opacityAt } from "../src/transfer.js";

const ramp = () => create(TransferFunctionSchema, {
  preset: "ct-bone",
  points: [
    { value: 0, opacity: 0, diffuse: { r: 1, g: 0, b: 0 } },
    { value: 100, opacity: 1, diffuse: { r: 0, g: 0, b: 1 } },
  ],
});

test("an added point takes the material where it lands, keeps the order and clears the preset", () => {
  const added = addPoint(ramp(), 50, 0.3)!;
  assert.equal(added.index, 1);
  assert.deepEqual(added.tf.points.map((p) => p.value), [0, 50, 100]);
  assert.equal(added.tf.preset, "");
  assert.ok(Math.abs(added.tf.points[1].diffuse!.r - 0.5) < 1e-9);
  assert.equal(addPoint(ramp(), 1e-9, 0.5), null, "too close to a point");
  assert.equal(addPoint(ramp(), NaN, 0.5), null);
});

test("a moved point stays between its neighbours; opacity is clamped", () => {
  const tf = addPoint(ramp(), 50, 0.5)!.tf;
  const moved = movePoint(tf, 1, 500, 7)!;
  assert.ok(moved.points[1].value < 100 && moved.points[1].value > 99);
  assert.equal(moved.points[1].opacity, 1);
  assert.equal(movePoint(tf, 9, 1, 1), null);
});

test("two points are always kept", () => {
  assert.equal(deletePoint(ramp(), 0), null);
  assert.equal(deletePoint(addPoint(ramp(), 50, 0.5)!.tf, 1)!.points.length, 2);
});

test("window/level shifts and scales about the centre, and keeps values increasing", () => {
  const tf = applyWindowLevel(ramp(), 10, 2);
  assert.deepEqual(tf.points.map((p) => p.value), [-40, 160]);
  assert.deepEqual(applyWindowLevel(ramp(), NaN, -1).points.map((p) => p.value), [0, 100]);
  const narrow = applyWindowLevel(ramp(), 0, 1e-9);  // clamped to 0.05
  assert.ok(narrow.points[1].value > narrow.points[0].value);
});

test("opacity is piecewise linear and constant beyond the ends", () => {
  assert.equal(opacityAt(ramp(), 25), 0.25);
  assert.equal(opacityAt(ramp(), -5), 0);
  assert.equal(opacityAt(ramp(), 1e9), 1);
});

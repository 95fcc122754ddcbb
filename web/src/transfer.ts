// Transfer-function edits, as the desktop viewer makes them
// (client-cpp/viewer/transfer_edits.cpp): add, move and delete points, and
// window/level. Each clears the preset, since the points now define the
// function. Pure: the editor's canvas and the tests call them alike.
import { create } from "@bufbuild/protobuf";
import {
  ColorSchema, TransferFunctionPointSchema, TransferFunctionSchema,
  type Color, type TransferFunction, type TransferFunctionPoint,
} from "../gen/cinevol/v1/scene_pb.js";

const clamp = (v: number, lo: number, hi: number) => Math.min(hi, Math.max(lo, v));

/** Smallest gap kept between neighbouring point values: 1e-4 of their span. */
export function minPointGap(tf: TransferFunction): number {
  const p = tf.points;
  if (p.length === 0) return 1e-6;
  const front = p[0].value, back = p[p.length - 1].value;
  return Math.max((back - front) * 1e-4, Math.max(Math.abs(front), Math.abs(back)) * 1e-6, 1e-6);
}

function copy(tf: TransferFunction): TransferFunction {
  return create(TransferFunctionSchema, { ...tf, preset: "", points: tf.points.map((p) => ({ ...p })) });
}

/** Moves point `index` between its neighbours; null for an index out of range. */
export function movePoint(tf: TransferFunction, index: number, value: number, opacity: number): TransferFunction | null {
  const n = tf.points.length;
  if (index < 0 || index >= n || !Number.isFinite(value) || !Number.isFinite(opacity)) return null;
  const gap = minPointGap(tf);
  const previous = index > 0 ? tf.points[index - 1].value : -Number.MAX_VALUE;
  const next = index + 1 < n ? tf.points[index + 1].value : Number.MAX_VALUE;
  const lo = previous + gap, hi = next - gap;
  const out = copy(tf);
  out.points[index].value = lo <= hi ? clamp(value, lo, hi) : 0.5 * (previous + next);
  out.points[index].opacity = clamp(opacity, 0, 1);
  return out;
}

function mix(a: number, b: number, t: number): number {
  return a + (b - a) * t;
}

function mixColor(a: Color | undefined, b: Color | undefined, t: number): Color {
  const x = a ?? create(ColorSchema), y = b ?? create(ColorSchema);
  return create(ColorSchema, { r: mix(x.r, y.r, t), g: mix(x.g, y.g, t), b: mix(x.b, y.b, t) });
}

/** Between which points `value` falls, and how far (beyond the ends: the end point). */
function locate(points: TransferFunctionPoint[], value: number): { lo: number; hi: number; t: number } {
  const i = points.findIndex((p) => p.value > value);
  if (i === 0) return { lo: 0, hi: 0, t: 0 };
  if (i < 0) return { lo: points.length - 1, hi: points.length - 1, t: 0 };
  return { lo: i - 1, hi: i, t: (value - points[i - 1].value) / (points[i].value - points[i - 1].value) };
}

/** A new point with the material of the function where it lands (white diffuse in an empty one). */
export function addPoint(tf: TransferFunction, value: number, opacity: number): { tf: TransferFunction; index: number } | null {
  if (!Number.isFinite(value)) return null;
  const gap = minPointGap(tf);
  if (tf.points.some((p) => Math.abs(p.value - value) < gap)) return null;
  const out = copy(tf);
  let point: TransferFunctionPoint;
  if (out.points.length === 0) {
    point = create(TransferFunctionPointSchema, {
      diffuse: { r: 1, g: 1, b: 1 }, specular: {}, roughness: 0.5, emission: {},
    });
  } else {
    const s = locate(out.points, value), a = out.points[s.lo], b = out.points[s.hi];
    point = create(TransferFunctionPointSchema, {
      diffuse: mixColor(a.diffuse, b.diffuse, s.t), specular: mixColor(a.specular, b.specular, s.t),
      roughness: mix(a.roughness, b.roughness, s.t), emission: mixColor(a.emission, b.emission, s.t),
    });
  }
  point.value = value;
  point.opacity = Number.isFinite(opacity) ? clamp(opacity, 0, 1) : 0;
  let index = out.points.findIndex((p) => p.value > value);
  if (index < 0) index = out.points.length;
  out.points.splice(index, 0, point);
  return { tf: out, index };
}

/** Deletes a point, keeping at least two; null when it cannot. */
export function deletePoint(tf: TransferFunction, index: number): TransferFunction | null {
  if (tf.points.length <= 2 || index < 0 || index >= tf.points.length) return null;
  const out = copy(tf);
  out.points.splice(index, 1);
  return out;
}

/**
 * Window/level: shifts every point by `levelDelta` and scales their spread
 * about the centre by `windowScale` (clamped to [0.05, 20]).
 */
export function applyWindowLevel(tf: TransferFunction, levelDelta: number, windowScale: number): TransferFunction {
  if (tf.points.length === 0) return tf;
  if (!Number.isFinite(levelDelta)) levelDelta = 0;
  windowScale = windowScale > 0 ? clamp(windowScale, 0.05, 20) : 1;
  const out = copy(tf);
  const centre = 0.5 * (out.points[0].value + out.points[out.points.length - 1].value);
  for (const p of out.points) p.value = centre + levelDelta + (p.value - centre) * windowScale;
  for (let i = 1; i < out.points.length; ++i) {  // rounding may make scaled values collide
    const previous = out.points[i - 1].value;
    if (out.points[i].value <= previous) out.points[i].value = previous + Math.max(Math.abs(previous) * 1e-7, 1e-6);
  }
  return out;
}

/** Piecewise-linear opacity; beyond the ends the end point's. */
export function opacityAt(tf: TransferFunction, value: number): number {
  if (tf.points.length === 0) return 0;
  const s = locate(tf.points, value);
  return mix(tf.points[s.lo].opacity, tf.points[s.hi].opacity, s.t);
}

/** Piecewise-linear diffuse colour, for drawing the curve. */
export function diffuseAt(tf: TransferFunction, value: number): Color {
  if (tf.points.length === 0) return create(ColorSchema);
  const s = locate(tf.points, value);
  return mixColor(tf.points[s.lo].diffuse, tf.points[s.hi].diffuse, s.t);
}

// What is drawn over the 3D view, where the frame shows: the slices'
// planes (the 2x2 layout) and the measurements, both in patient
// coordinates, through the state's placement into the camera's frame and
// projected as the server's pinhole camera does; and everyone else's
// pointer in a shared session.
import { SliceAxis } from "../gen/cinevol/v1/service_pb.js";
import type { ViewCamera } from "./camera.js";
import { measurementText, projectToView } from "./measure.js";
import { toVolume, type Placement } from "./placement.js";
import { drawPointers, type FrameRect, type Pointer } from "./pointers.js";
import type { Measurement } from "./reading.js";
import type { V3 } from "./vec.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
/** The slice planes on the 3D view in 3D Slicer's colours: axial red, coronal green, sagittal yellow. */
const PLANE_COLOURS: Partial<Record<SliceAxis, string>> = {
  [SliceAxis.AXIAL]: "#e44", [SliceAxis.CORONAL]: "#4c4", [SliceAxis.SAGITTAL]: "#ec4",
};

/** What the overlay shows now. */
export interface OverlayContent {
  frame: FrameRect | null;  // where the newest frame shows in the view; null before the first
  camera?: ViewCamera;
  placement?: Placement;
  planes: { axis: SliceAxis; outline: V3[] }[];  // LPS mm
  measurements: readonly Measurement[];
  pointers: readonly Pointer[];
}

export function drawOverlay(content: OverlayContent): void {
  const canvas = $<HTMLCanvasElement>("view-overlay"), view = $<HTMLCanvasElement>("view");
  const g = canvas.getContext("2d");
  if (!g) return;
  canvas.width = view.clientWidth;
  canvas.height = view.clientHeight;
  const rect = content.frame ?? { left: 0, top: 0, width: canvas.width, height: canvas.height };
  drawPlanesAndMeasurements(g, rect, content);
  drawPointers(g, content.pointers, rect);
}

function drawPlanesAndMeasurements(g: CanvasRenderingContext2D, rect: FrameRect, content: OverlayContent): void {
  const { camera, placement } = content;
  if (!camera || !placement) return;
  const onView = (p: V3) => {
    const q = projectToView(camera, toVolume(placement, p), rect.width, rect.height);
    return q && { x: rect.left + q.x, y: rect.top + q.y };
  };
  g.lineWidth = 1.5;
  for (const plane of content.planes) {
    const points = plane.outline.map(onView);
    if (points.length === 0 || points.some((p) => !p)) continue;
    g.strokeStyle = PLANE_COLOURS[plane.axis] ?? "#ccc";
    g.beginPath();
    points.forEach((p, i) => (i ? g.lineTo(p!.x, p!.y) : g.moveTo(p!.x, p!.y)));
    g.closePath();
    g.stroke();
  }
  g.strokeStyle = g.fillStyle = "#4df";
  g.lineWidth = 2;
  g.font = "12px system-ui, sans-serif";
  for (const m of content.measurements) {
    const points = m.points.map(onView);
    if (points.some((p) => !p)) continue;
    g.beginPath();
    points.forEach((p, i) => (i ? g.lineTo(p!.x, p!.y) : g.moveTo(p!.x, p!.y)));
    g.stroke();
    for (const p of points) g.fillRect(p!.x - 2, p!.y - 2, 4, 4);
    const last = points[points.length - 1]!;
    g.fillText(measurementText(m.points), last.x + 6, last.y - 6);
  }
}

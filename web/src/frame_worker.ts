// Decodes frames off the page's main thread and draws them onto the
// canvas it was handed (an OffscreenCanvas). Only the newest frame waits:
// one that arrives while another decodes replaces the one waiting.
/// <reference lib="webworker" />
import type { FrameMeta, ToWorker } from "./frame_messages.js";

let canvas: OffscreenCanvas | undefined;
let context: OffscreenCanvasRenderingContext2D | null = null;
let waiting: { bytes: ArrayBuffer; type: string; meta: FrameMeta } | undefined;
let decoding = false;
let replaced = 0;

const post = (message: unknown) => (self as unknown as Worker).postMessage(message);

async function drain(): Promise<void> {
  decoding = true;
  while (waiting) {
    const frame = waiting;
    waiting = undefined;
    try {
      const start = performance.now();
      const bitmap = await createImageBitmap(new Blob([frame.bytes], { type: frame.type }));
      if (canvas && context) {
        // The frame's size, which a frame rendered smaller while the view
        // moves is stretched to (StreamSettings.framesAtRenderedSize).
        const { width, height } = frame.meta;
        if (canvas.width !== width || canvas.height !== height) {
          canvas.width = width;
          canvas.height = height;
        }
        context.drawImage(bitmap, 0, 0, width, height);
      }
      bitmap.close();
      const end = performance.now();
      post({ painted: frame.meta, at: performance.timeOrigin + end, decodeMs: end - start, replaced });
    } catch (e) {
      post({ error: `frame ${frame.meta.id} could not be decoded: ${e}` });
    }
  }
  decoding = false;
}

/** Mean luminance over a grid of cells, for tests that ask whether the picture changed. */
function sample(cells: number): { width: number; height: number; grid: number[] } {
  if (!canvas || !context || canvas.width === 0) return { width: 0, height: 0, grid: [] };
  const { width, height } = canvas;
  const pixels = context.getImageData(0, 0, width, height).data;
  const sums = new Array<number>(cells * cells).fill(0), counts = new Array<number>(cells * cells).fill(0);
  for (let y = 0; y < height; ++y) {
    for (let x = 0; x < width; ++x) {
      const i = 4 * (y * width + x), cell = Math.floor((y * cells) / height) * cells + Math.floor((x * cells) / width);
      sums[cell] += 0.2126 * pixels[i] + 0.7152 * pixels[i + 1] + 0.0722 * pixels[i + 2];
      counts[cell] += 1;
    }
  }
  return { width, height, grid: sums.map((s, i) => s / Math.max(1, counts[i])) };
}

self.onmessage = (event: MessageEvent<ToWorker>) => {
  const m = event.data;
  if (m.kind === "canvas") {
    canvas = m.canvas;
    context = canvas.getContext("2d", { alpha: false });
  } else if (m.kind === "frame") {
    if (waiting) replaced += 1;
    waiting = m;
    if (!decoding) void drain();
  } else if (m.kind === "sample") {
    post({ sample: sample(m.cells), id: m.id });
  }
};

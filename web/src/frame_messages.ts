// What the page and its frame worker (frame_worker.ts) say to each other.
export interface FrameMeta {
  id: bigint;
  lastEventSeq: bigint;
  width: number;
  height: number;
  bytes: number;
  final: boolean;
}

export type ToWorker =
  | { kind: "canvas"; canvas: OffscreenCanvas }
  | { kind: "frame"; bytes: ArrayBuffer; type: string; meta: FrameMeta }
  | { kind: "sample"; cells: number; id: number };

export type FromWorker =
  | { painted: FrameMeta; at: number; decodeMs: number; replaced: number }  // decodeMs: decode and draw
  | { error: string }
  | { sample: { width: number; height: number; grid: number[] }; id: number };

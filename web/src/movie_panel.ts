// "Record a movie": the session's view along an orbit, a sweep or a time series' phases, made by the server (RenderMovie: every frame a
// refined still, H.264 in an MP4; docs/movies.md), its progress in the message line, then saved by the browser.
import { SliceAxis } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

/** The path a choice names: a whole turn of the camera, a clip plane across a patient axis, or the phases played. */
export function moviePath(choice: string): { case: "orbitDegrees"; value: number } | { case: "sweep"; value: SliceAxis }
    | { case: "phases"; value: boolean } {
  const sweeps: Record<string, SliceAxis> = {
    "sweep-axial": SliceAxis.AXIAL, "sweep-coronal": SliceAxis.CORONAL, "sweep-sagittal": SliceAxis.SAGITTAL,
  };
  if (choice === "phases") return { case: "phases", value: true };
  return choice in sweeps ? { case: "sweep", value: sweeps[choice] } : { case: "orbitDegrees", value: 360 };
}

export class MoviePanel {
  private recording = false;

  constructor(private readonly api: Api, private readonly sessionId: () => string | undefined,
              private readonly say: (text: string) => void, private readonly error: (text: string) => void) {
    $("movie-record").addEventListener("click", () => void this.record());
  }

  private async record(): Promise<void> {
    const sessionId = this.sessionId();
    if (!sessionId) return this.error("No session is open: there is nothing to record.");
    if (this.recording) return;
    this.recording = true;
    $<HTMLButtonElement>("movie-record").disabled = true;
    try {
      let mp4: Uint8Array | undefined;
      for await (const update of this.api.sessions.renderMovie({
        sessionId, path: moviePath($<HTMLSelectElement>("movie-path").value),
        seconds: Number($<HTMLInputElement>("movie-seconds").value), fps: 25,
        spp: Number($<HTMLSelectElement>("movie-quality").value),
      })) {
        if (update.update.case === "progress") {
          const p = update.update.value;
          this.say(`Recording the movie: frame ${p.framesDone} of ${p.frames}, ${p.spp} samples a pixel each`);
        } else if (update.update.case === "movie") {
          mp4 = update.update.value.mp4;
          this.say(`Movie recorded: ${update.update.value.frames} frames, ` +
                   `${(Number(update.update.value.renderUs) / 1e6).toFixed(1)} s to render`);
        }
      }
      if (mp4) save(mp4, "cinevol-movie.mp4");
    } catch (e) {
      this.error(plainWords(e));
    } finally {
      this.recording = false;
      $<HTMLButtonElement>("movie-record").disabled = false;
    }
  }
}

function save(bytes: Uint8Array, name: string): void {
  const link = document.createElement("a");
  link.href = URL.createObjectURL(new Blob([bytes.slice()], { type: "video/mp4" }));
  link.download = name;
  link.click();
  setTimeout(() => URL.revokeObjectURL(link.href), 1000);
}

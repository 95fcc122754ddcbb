// A time series' controls (Scene.time): the phase shown, play and pause, and
// the rate (phases a second; 0: the series' own times). Shown only for a
// volume of several phases. The server plays the series: the label follows
// the phase of the frames it sends.
import { create } from "@bufbuild/protobuf";
import { TimeSchema, type Scene } from "../gen/cinevol/v1/scene_pb.js";
import type { Frame, VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { PageLink } from "./page_link.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export class TimePanel {
  private phases = 1;
  private seconds: number[] = [];
  private playing = false;

  constructor(private readonly link: PageLink) {
    $("phase").addEventListener("input", () => this.send(false));
    $("play").addEventListener("click", () => this.send(!this.playing));
    $("phase-rate").addEventListener("change", () => this.send(this.playing));
  }

  setVolume(volume: VolumeInfo | undefined): void {
    this.phases = Math.max(1, volume?.phases ?? 1);
    this.seconds = volume?.phaseSeconds ?? [];
    $("time").hidden = this.phases < 2;
    $("movie-phases").hidden = this.phases < 2;  // a movie of the loop (Output panel)
    $<HTMLInputElement>("phase").max = String(this.phases - 1);
    this.label(0);
  }

  /** The server's state: where the series stands (a drag of the slider keeps its own while newer). */
  show(scene: Scene): void {
    const time = scene.time;
    this.playing = !!time?.playing;
    $("play").textContent = this.playing ? "Pause" : "Play";
    if (this.link.ahead("time")) return;
    $<HTMLInputElement>("phase").value = String(time?.phase ?? 0);
    $<HTMLInputElement>("phase-rate").value = String(time?.phasesPerSecond ?? 0);
    this.label(time?.phase ?? 0);
  }

  /** A frame: the phase it shows, while playing. */
  shown(frame: Frame): void {
    if (this.phases < 2 || !this.playing) return;
    $<HTMLInputElement>("phase").value = String(frame.phase);
    this.label(frame.phase);
  }

  private send(playing: boolean): void {
    const phase = Number($<HTMLInputElement>("phase").value);
    const rate = Math.max(0, Math.min(120, Number($<HTMLInputElement>("phase-rate").value) || 0));
    this.label(phase);
    this.link.post({ case: "time", value: create(TimeSchema, { phase, playing, phasesPerSecond: rate }) });
  }

  private label(phase: number): void {
    const at = this.seconds[phase];
    $("phase-label").textContent = `Phase ${phase + 1} of ${this.phases}` +
      (at === undefined ? "" : ` (${(at * 1000).toFixed(0)} ms)`);
  }
}

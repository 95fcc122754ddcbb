// The transfer function as the page shows and edits it: the preset list
// (a preset is asked of the server by name; the state brings its points),
// the editor over the histogram, and Alt-drag's window/level on the 3D view.
// The points edited are the state's, or this page's own edit while it is
// newer than the state, so that a drag's steps add up.
import { create } from "@bufbuild/protobuf";
import { TransferFunctionSchema, type TransferFunction } from "../gen/cinevol/v1/scene_pb.js";
import type { SessionState, VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { PageLink } from "./page_link.js";
import { TransferEditor } from "./tf_editor.js";
import { applyWindowLevel } from "./transfer.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

export class TransferPanel {
  private readonly editor = new TransferEditor($("tf-editor"), $("tf-note"));
  private tf?: TransferFunction;

  constructor(private readonly link: PageLink) {
    this.editor.onEdit = (tf) => this.edit(tf);
    $("preset").addEventListener("change", () => {
      const preset = $<HTMLSelectElement>("preset").value;
      if (preset) this.link.post({ case: "transferFunction", value: create(TransferFunctionSchema, { preset }) });
    });
  }

  /** The presets the server offers (ServerStatus.presets); `choose`: an empty first choice. */
  offer(presets: readonly string[], choose: boolean): void {
    const options = presets.map((p) => new Option(p, p));
    $<HTMLSelectElement>("preset").replaceChildren(...(choose ? [new Option("(choose a preset)", ""), ...options] : options));
  }

  /** A volume described: its histogram under the curve. */
  setVolume(volume: VolumeInfo | undefined): void {
    this.editor.show(undefined, volume?.histogram);
  }

  adopt(state: SessionState): void {
    const tf = state.scene?.transferFunction;
    $<HTMLSelectElement>("preset").value = tf?.preset ?? "";
    if (this.link.ahead("transferFunction")) return;
    this.tf = tf;
    this.editor.show(tf);
  }

  /** Alt-drag: window (horizontal) and level (vertical), in steps of the volume's value range. */
  windowLevel(dx: number, dy: number): void {
    const tf = this.tf, volume = this.link.volume;
    if (!tf || tf.points.length === 0 || !volume || !this.link.state || !this.link.driving) return;
    const range = volume.maxValue - volume.minValue || 1;
    const edited = applyWindowLevel(tf, (-dy * range) / 500, Math.exp(dx * 0.005));
    this.editor.show(edited);
    this.edit(edited);
  }

  private edit(tf: TransferFunction): void {
    if (!this.link.driving || !this.link.state) return;  // none before a new session's first state
    this.tf = tf;
    this.link.post({ case: "transferFunction", value: tf });
  }
}

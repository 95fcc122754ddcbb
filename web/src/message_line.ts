// The line over the 3D view: one message at a time (messages.ts says
// which), an error as an alert until cleared, news as a polite status that
// may pass, else what the page waits for; and the last messages said, for
// tests and scripts.
import { messageToShow, type Messages, type Shown } from "./messages.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const PASSING_MS = 6000;

export class MessageLine {
  private readonly said: Messages = { error: "", banner: "", waiting: "Connecting to the server…" };
  private readonly history: string[] = [];  // what the banner and the error line said, newest last
  /** Called with every error shown: nothing more will come to wait for. */
  onError: () => void = () => {};

  constructor() {
    this.show();
  }

  get error(): string {
    return this.said.error;
  }

  get banner(): string {
    return this.said.banner;
  }

  get waiting(): string {
    return this.said.waiting;
  }

  get shown(): Shown | null {
    return messageToShow(this.said);
  }

  get messages(): string[] {
    return [...this.history];
  }

  /** Says how things are; a passing message clears itself unless another came meanwhile. */
  setBanner(text: string, passing = false): void {
    this.remember(text);
    this.said.banner = text;
    this.show();
    if (passing) setTimeout(() => this.said.banner === text && this.setBanner(""), PASSING_MS);
  }

  showError(text: string): void {
    this.remember(text);
    if (text) this.onError();
    this.said.error = text;
    this.show();
  }

  /** What the page waits for, said while nothing else is; "" once there is a picture. */
  setWaiting(text: string): void {
    this.said.waiting = text;
    this.show();
  }

  /** One message at a time over the view: the error line (an alert) or the banner (a polite status). */
  private show(): void {
    const shown = messageToShow(this.said);
    for (const kind of ["error", "banner"] as const) {
      $(kind).textContent = shown?.kind === kind ? shown.text : "";
      $(kind).hidden = shown?.kind !== kind;
    }
  }

  private remember(text: string): void {
    if (!text) return;
    this.history.push(text);
    if (this.history.length > 20) this.history.shift();
  }
}

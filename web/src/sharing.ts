// A shared session as this page lives it (docs/web.md, "Sharing a
// session"): whether it drives (the owner always, a share's holder while it
// presents), the controls off while it does not, the line saying who
// presents and how many watch, this page's pointer sent while anyone
// watches, everyone else's to draw, and the presenter's role handed back.
import { create } from "@bufbuild/protobuf";
import { Code, type ConnectError } from "@connectrpc/connect";
import { PointerSchema, type SessionState } from "../gen/cinevol/v1/service_pb.js";
import type { MessageLine } from "./message_line.js";
import type { PageLink } from "./page_link.js";
import { echoedName, othersPointers, Throttle, type Fraction, type Pointer } from "./pointers.js";
import { ownName, presence, type SharePanel } from "./share.js";
import { shareWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
/** The controls that send events: disabled while this page does not drive (a share's viewer). */
const DRIVING = "#preset, #view-controls button, #clipping input, #labels-panel input, #light input, #lossless, #quality";

export class Sharing {
  private readonly pointer = new Throttle<Fraction | null>((at) => this.sendPointer(at));
  private pointerSent?: Fraction;  // where this page's pointer went last (undefined: hidden)
  private pointerRefused = false;  // this share does not allow a pointer (until the presenter changes)
  private echoedName?: string;     // one's own name, from the server's echo of one's pointer
  private before?: SessionState;

  constructor(private readonly link: PageLink, private readonly panel: SharePanel, private readonly said: MessageLine) {
    $("hand-back").addEventListener("click", () => void this.handBack());
  }

  /** This page's name as the server writes it (SessionState.presenter, pointers' `who`). */
  ownName(): string | undefined {
    return this.echoedName ?? ownName(this.link.session?.owner, this.link.session?.grant ?? "");
  }

  /** Everyone's pointer but this page's own. */
  others(): Pointer[] {
    return othersPointers(this.link.state?.pointers ?? [], this.ownName());
  }

  /** Who presents and how many watch; the share's list follows its watchers. */
  adopt(state: SessionState): void {
    const before = this.before;
    this.before = state;
    this.echoedName = echoedName(state.pointers, this.pointerSent) ?? this.echoedName;
    if (before && before.presenter !== state.presenter) this.pointerRefused = false;  // a hand-over may allow it now
    const driving = !this.link.shared || (state.presenter !== "" && state.presenter === this.ownName());
    if (driving !== this.link.driving) this.setDriving(driving);
    const line = presence(state, this.ownName(), this.link.shared);
    $("presence").textContent = line;
    $("presence").hidden = !line;
    if (before?.viewers !== state.viewers || before?.presenter !== state.presenter) void this.panel.refresh();
  }

  setDriving(on: boolean): void {
    this.link.driving = on;
    document.body.classList.toggle("watching", !on);
    for (const control of document.querySelectorAll<HTMLInputElement>(DRIVING)) control.disabled = !on;
    $("hand-back").hidden = !on || !this.link.shared;
  }

  /** A refused batch of pointers: this share allows none, said once. True where that was it. */
  refusedPointer(kinds: string[], error: ConnectError): boolean {
    if (error.code !== Code.PermissionDenied || !kinds.every((k) => k === "pointer")) return false;
    this.pointerRefused = true;
    this.said.setBanner("Your pointer is not shown to the others: this share does not allow it.", true);
    return true;
  }

  /** This page's pointer over the frame, while anyone watches: at most 20 a second, `null` once it leaves. */
  point(at: Fraction | null): void {
    if (!this.link.state?.viewers || this.pointerRefused || (!at && !this.pointerSent)) return;
    this.pointer.push(at);
  }

  private sendPointer(at: Fraction | null): void {
    this.pointerSent = at ?? undefined;
    this.link.post({ case: "pointer", value: create(PointerSchema, at ? { x: at.x, y: at.y } : { hidden: true }) });
  }

  /** A share's presenter gives the role back to the owner. */
  private async handBack(): Promise<void> {
    try {
      await this.link.api.sessions.handOver({ grant: this.link.session?.grant ?? "", grantId: "" });
    } catch (e) {
      this.said.showError(shareWords(e));
    }
  }
}

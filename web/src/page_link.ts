// The page's link to its session: which session it shows (one's own,
// opened or joined, or one shared with this page), the volume's
// description, the newest state the server sent and where the volume lies
// (state.placement), and the one way to change anything: an event. Every
// room of the page reads the state here and posts its edits here; none
// works out what the server would (a named view's camera, a preset's
// points): each shows the state it is given.
import type { ConnectError } from "@connectrpc/connect";
import type { Frame, Notice, SessionState, VolumeInfo } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import type { MessageLine } from "./message_line.js";
import { placementOf, type Placement } from "./placement.js";
import { LiveSession, now, type EventKind, type SessionHandlers, type SessionStart } from "./session.js";
import type { MotionToPhoton } from "./stats.js";
import { plainWords } from "./words.js";

const INPUT_RECENT_MS = 100;  // an input event this recent is what an event answers

/** What the page does with what the session brings; `state` comes after the link took it. */
export type LinkHandlers = SessionHandlers & {
  /** A volume described (a session opened or joined), or none (a share's page knows none). */
  volume(volume: VolumeInfo | undefined): void;
};

export class PageLink {
  session?: LiveSession;
  state?: SessionState;
  /** DescribeVolume's answer: histogram, labels, values, the patient; a share's page has none. */
  volume?: VolumeInfo;
  /** Where the volume lies in the patient, from the newest state. */
  placement?: Placement;
  /** Whether this page may drive: the owner always, a share's holder while it presents. */
  driving = true;

  /** `inputAt`: when the input behind an event came (the view's newest pointer, wheel or key event). */
  constructor(readonly api: Api, private readonly handlers: LinkHandlers, private readonly said: MessageLine,
              private readonly latency: MotionToPhoton, private readonly inputAt: () => number) {}

  /** Watching by a share's secret: a viewer, or its presenter. */
  get shared(): boolean {
    return Boolean(this.session?.grant);
  }

  /** A new session of a volume of the server's (a scene, a preset, or the volume's default); false where it failed, in words. */
  async open(volumeId: string, viewport: { width: number; height: number }, start: SessionStart = {}): Promise<boolean> {
    this.session?.close();
    this.state = this.placement = undefined;  // the old session's, until the new one's first state
    this.said.showError("");
    this.said.setWaiting(`Opening ${volumeId}…`);
    try {
      await this.describe(volumeId);
      this.session = await LiveSession.create(this.api, this.sessionHandlers(), this.latency, volumeId, viewport, start);
      this.said.setWaiting("Waiting for the first frame…");
      return true;
    } catch (e) {
      this.said.showError(plainWords(e));
      return false;
    }
  }

  /** A session of one's own that exists (a reload, or a link naming it); false where it failed, in words. */
  async join(sessionId: string): Promise<boolean> {
    this.said.setWaiting("Joining the session…");
    try {
      this.session = await LiveSession.join(this.api, this.sessionHandlers(), this.latency, sessionId);
      this.said.setWaiting("Waiting for the first frame…");
      if (this.session.volumeId) await this.describe(this.session.volumeId);
      return true;
    } catch (e) {
      this.said.showError(plainWords(e));
      return false;
    }
  }

  /** A session shared with this page (#grant=): the state says all there is to show. */
  watchShared(grant: string): void {
    this.said.setWaiting("Waiting for the shared session's first frame…");
    this.session = LiveSession.watchShared(this.api, this.sessionHandlers(), this.latency, grant);
  }

  private async describe(volumeId: string): Promise<void> {
    this.volume = await this.api.volumes.describeVolume({ volumeId });
    this.handlers.volume(this.volume);
  }

  /**
   * Sends an event, where this page may: a pointer always; the viewport only
   * from the owner's window; the rest while it drives. Motion-to-photon
   * counts from the input event behind it (or now, for one without).
   */
  post(kind: EventKind): void {
    const may = kind.case === "pointer" || (kind.case === "resize" ? !this.shared : this.driving);
    if (!may) return;
    const t = now(), input = this.inputAt();
    this.session?.post(kind, t - input < INPUT_RECENT_MS ? input : t);
  }

  /** This page's own edit of this kind is newer than the state (LiveSession.ahead): it shows its own until then. */
  ahead(kind: EventKind["case"]): boolean {
    return this.session?.ahead(kind, this.state) ?? false;
  }

  private sessionHandlers(): SessionHandlers {
    const h = this.handlers;
    return {
      attached: (id: string) => h.attached(id),
      frame: (frame: Frame) => h.frame(frame),
      state: (state: SessionState) => {
        this.state = state;
        this.placement = placementOf(state.placement);
        h.state(state);
      },
      notice: (n: Notice) => h.notice(n),
      refused: (kinds: EventKind["case"][], error: ConnectError) => h.refused(kinds, error),
      banner: (text: string, passing?: boolean) => h.banner(text, passing),
      failed: (text, code) => h.failed(text, code),
    };
  }
}

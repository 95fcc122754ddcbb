// A session as the page lives it: create or join, watch its frames
// (WatchSession), send its events in batches (SendEvents), and keep going
// through a lost connection or gateway: the same session resumed, or a new
// one made from the last state the server sent when the old one is gone.
// A shared session (a grant's secret, docs/web.md "Sharing a session") is
// watched and driven the same way, the grant in each call; it never makes a
// session of its own. The page never re-derives the state from its events:
// it shows what the server answers.
import { create, type MessageInitShape } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import type { Scene } from "../gen/cinevol/v1/scene_pb.js";
import {
  SessionEventSchema, type Frame, type Notice, type SessionEvent, type SessionState, type ViewportSchema,
} from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import type { MotionToPhoton } from "./stats.js";
import { plainWords, shareWords } from "./words.js";

/** How a new session starts: a scene (a presentation state's), a preset, or neither (the volume's default). */
export interface SessionStart {
  preset?: string;
  scene?: Scene;
}

/** One kind of event, e.g. { case: "camera", value: camera }. */
export type EventKind = Exclude<SessionEvent["kind"], { case: undefined }>;

export interface SessionHandlers {
  attached(sessionId: string): void;
  frame(frame: Frame): void;
  state(state: SessionState): void;
  notice(notice: Notice): void;
  /** The server refused a batch of events (of these kinds); the session goes on. */
  refused(kinds: EventKind["case"][], error: ConnectError): void;
  /** How the connection is, in words; `passing`: it clears itself after a while. */
  banner(text: string, passing?: boolean): void;
  /** The session cannot go on: why, in words, and the server's code where it refused. */
  failed(text: string, code?: Code): void;
}

const ENDED_TRAILER = "cinevol-session-ended";
const MAX_RETRY_MS = 4000;
const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));
export const now = () => performance.timeOrigin + performance.now();

// Refusals that another try would meet again.
// Events no frame answers: they change no picture (the state shares them).
const UNANSWERED = new Set<EventKind["case"]>(["pointer", "measurements"]);

const FINAL = new Set([Code.Unauthenticated, Code.PermissionDenied, Code.Aborted, Code.InvalidArgument,
                       Code.Unimplemented]);

export class LiveSession {
  private seq = 0n;
  private answeredSeq = 0n;  // the newest event a frame will answer (UNANSWERED kinds change no picture)
  private readonly pending = new Map<string, { kind: EventKind; inputAt: number }>();
  private readonly inFlight = new Set<string>();          // the kinds of the batch on its way
  private readonly sentSeq = new Map<string, bigint>();  // the newest event of each kind sent since the attach
  private sending = false;
  private attached = false;
  private closed = false;
  private abort = new AbortController();
  state?: SessionState;
  /** The owner's principal as the server names it (ServerStatus), where known: pointers and the presenter use it. */
  owner?: string;
  /** Events sent since the page opened, by kind. */
  readonly sentKinds: Partial<Record<EventKind["case"], number>> = {};

  /** `grant`: a share's secret; the session is then the grant's (`id` may stay empty) and never one's own. */
  private constructor(private readonly api: Api, private readonly handlers: SessionHandlers,
                      private readonly latency: MotionToPhoton, public id: string, readonly volumeId: string,
                      readonly grant = "") {}

  /** A new session of `volumeId` (its scene, its preset or the volume's default), watched at once. */
  static async create(api: Api, handlers: SessionHandlers, latency: MotionToPhoton, volumeId: string,
                      viewport: MessageInitShape<typeof ViewportSchema>, start: SessionStart = {}): Promise<LiveSession> {
    const initial = start.scene ? { case: "scene" as const, value: start.scene }
      : start.preset ? { case: "preset" as const, value: start.preset } : { case: undefined };
    // The frame worker stretches a frame rendered smaller: the server need not upsample it.
    const created = await api.sessions.createSession({ volumeId, viewport, initial, stream: { framesAtRenderedSize: true } });
    api.sessionAddress = created.address;
    const session = new LiveSession(api, handlers, latency, created.sessionId, volumeId);
    void api.server.getStatus({}).then((s) => {
      session.owner = s.sessions.find((x) => x.sessionId === session.id)?.owner;
    }).catch(() => {});
    void session.watch();
    return session;
  }

  /** An existing session of one's own (a reload, or a link that names it); its volume from the server's status. */
  static async join(api: Api, handlers: SessionHandlers, latency: MotionToPhoton,
                    sessionId: string): Promise<LiveSession> {
    const status = await api.server.getStatus({});
    const mine = status.sessions.find((s) => s.sessionId === sessionId);
    const session = new LiveSession(api, handlers, latency, sessionId, mine?.volumeId ?? "");
    session.owner = mine?.owner;
    void session.watch();
    return session;
  }

  /** The session a share's secret names (#grant=), watched as its holder: a viewer, or its presenter. */
  static watchShared(api: Api, handlers: SessionHandlers, latency: MotionToPhoton, grant: string): LiveSession {
    const session = new LiveSession(api, handlers, latency, "", "", grant);
    void session.watch();
    return session;
  }

  /**
   * Queues an event. While a batch is on its way, later events of the same
   * kind replace earlier ones (the newest camera wins), so the page sends
   * at the pace the server answers. `inputAt`: when the input behind it came.
   */
  post(kind: EventKind, inputAt = now()): void {
    const earlier = this.pending.get(kind.case);
    this.pending.set(kind.case, { kind, inputAt: Math.min(earlier?.inputAt ?? inputAt, inputAt) });
    void this.send();
  }

  /** The newest sequence number since the attach of an event a frame answers (0: none). */
  get lastSeq(): bigint {
    return this.answeredSeq;
  }

  /**
   * Is this page's own edit of this kind newer than `state`: waiting to go,
   * on its way, or answered by a state that does not include it yet (the
   * server applies events past its rate before the next frame)? While it
   * is, the page shows its own edit (the camera it drags, the points it
   * moves); after, the state's. A share's events are numbered by the
   * server, so for a share only the first two count.
   */
  ahead(kind: EventKind["case"], state: SessionState | undefined): boolean {
    if (this.pending.has(kind) || this.inFlight.has(kind)) return true;
    return !this.grant && state !== undefined && (this.sentSeq.get(kind) ?? 0n) > state.lastEventSeq;
  }

  /** Stops watching; one's own session also ends on the server (a shared one goes on for its owner). */
  close(): void {
    this.closed = true;
    this.abort.abort();
    if (!this.grant) this.api.sessions.closeSession({ sessionId: this.id }).catch(() => {});
  }

  private words(e: unknown): string {
    return this.grant ? shareWords(e) : plainWords(e);
  }

  private async send(): Promise<void> {
    if (this.sending || !this.attached || this.pending.size === 0) return;
    this.sending = true;
    const batch = [...this.pending.values()];
    this.pending.clear();
    const events = batch.map(({ kind, inputAt }) => {
      this.seq += 1n;
      this.inFlight.add(kind.case);
      this.sentSeq.set(kind.case, this.seq);
      this.sentKinds[kind.case] = (this.sentKinds[kind.case] ?? 0) + 1;
      // Motion-to-photon for the owner's events that change the picture; the server numbers a share's own.
      if (!UNANSWERED.has(kind.case)) this.answeredSeq = this.seq;
      if (!UNANSWERED.has(kind.case) && !this.grant) this.latency.sent(this.seq, inputAt);
      return create(SessionEventSchema, { seq: this.seq, kind });
    });
    try {
      const answer = await this.api.sessions.sendEvents({ sessionId: this.id, events, grant: this.grant });
      this.inFlight.clear();
      if (answer.state) this.adopt(this.withStreamSharing(answer.state));
    } catch (e) {
      this.inFlight.clear();
      const error = ConnectError.from(e);
      if (FINAL.has(error.code) || error.code === Code.ResourceExhausted || error.code === Code.FailedPrecondition) {
        for (const b of batch) this.sentSeq.delete(b.kind.case);  // refused: the state is the truth again
        this.handlers.refused(batch.map((b) => b.kind.case), error);
        if (this.state) this.handlers.state(this.state);  // the page shows the state again, not its refused edit
      } else {  // the connection broke: the events go again once the watch is back
        for (const b of batch) if (!this.pending.has(b.kind.case)) this.pending.set(b.kind.case, b);
      }
    } finally {
      this.sending = false;
    }
    void this.send();
  }

  private adopt(state: SessionState): void {
    this.state = state;
    this.handlers.state(state);
  }

  /**
   * A SendEvents answer is the state when the server took the call; who
   * presents, who watches and their pointers change by others' calls, which
   * the stream tells in order. An answer that comes back after the stream's
   * newer word (a hand-over while a pointer was in flight) would bring the old
   * presenter back, so those parts stay the stream's.
   */
  private withStreamSharing(answer: SessionState): SessionState {
    if (!this.state) return answer;
    answer.presenter = this.state.presenter;
    answer.viewers = this.state.viewers;
    answer.pointers = this.state.pointers;
    return answer;
  }

  private async watch(): Promise<void> {
    let retryMs = 250;
    let lost = false;
    while (!this.closed) {
      const outcome = await this.watchOnce(() => {
        retryMs = 250;
        if (lost) this.handlers.banner("Reconnected: the same session goes on.", true);
        lost = false;
      });
      if (this.closed) return;
      if (outcome.kind === "failed") return this.handlers.failed(outcome.text, outcome.code);
      if (outcome.kind === "closed") return this.handlers.failed("The session was closed on the server.");
      if (outcome.kind === "lost") {
        lost = true;
        this.handlers.banner(`Connection lost (${outcome.text}). Reconnecting to the same session…`);
        await sleep(retryMs);
        retryMs = Math.min(2 * retryMs, MAX_RETRY_MS);
        continue;
      }
      // The session itself ended (drained, failed, expired while away): go on in a new one, unless it was someone else's.
      if (this.grant) return this.handlers.failed(`The shared session ended on the server (${outcome.text}).`);
      if (!(await this.recreate(outcome.text))) return;
    }
  }

  /** One WatchSession call, until it ends: what ended it. */
  private async watchOnce(onAttach: () => void): Promise<
      { kind: "lost" | "ended"; text: string } | { kind: "failed"; text: string; code: Code } | { kind: "closed" }> {
    this.abort = new AbortController();
    let ended = false;
    try {
      const messages = this.api.sessions.watchSession({ sessionId: this.id, grant: this.grant }, {
        signal: this.abort.signal, onTrailer: (t) => { ended = t.has(ENDED_TRAILER); },
      });
      for await (const m of messages) {
        if (!this.attached) {  // the first message (the state) says the attach took: numbering starts again
          this.attached = true;
          this.seq = this.answeredSeq = 0n;
          this.sentSeq.clear();
          this.latency.reset();
          onAttach();
          this.handlers.attached(this.id);
          void this.send();
        }
        if (m.kind.case === "frame") this.handlers.frame(m.kind.value);
        else if (m.kind.case === "state") this.adopt(m.kind.value);
        else if (m.kind.case === "notice") this.handlers.notice(m.kind.value);
      }
      return ended ? { kind: "closed" } : { kind: "lost", text: "the stream ended" };
    } catch (e) {
      const error = ConnectError.from(e);
      if (error.metadata.has(ENDED_TRAILER) || error.code === Code.NotFound) {
        return { kind: "ended", text: error.rawMessage || "it no longer exists" };
      }
      if (FINAL.has(error.code)) return { kind: "failed", text: this.words(error), code: error.code };
      return { kind: "lost", text: error.rawMessage || "no answer" };
    } finally {
      this.attached = false;
    }
  }

  /** A new session from the last state the server sent (the server's own rule: CreateSession from a state). */
  private async recreate(reason: string): Promise<boolean> {
    const state = this.state;
    if (!state?.scene || !this.volumeId) {
      this.handlers.failed(`The session ended on the server (${reason}).`);
      return false;
    }
    for (let retryMs = 250; !this.closed; retryMs = Math.min(2 * retryMs, MAX_RETRY_MS)) {
      try {
        const created = await this.api.sessions.createSession({
          volumeId: this.volumeId, viewport: state.viewport, stream: state.stream,
          initial: { case: "scene", value: state.scene },
        });
        this.id = created.sessionId;
        this.api.sessionAddress = created.address;
        this.handlers.banner(`The session ended on the server (${reason}); a new one goes on from its last state.`,
                             true);
        return true;
      } catch (e) {
        const error = ConnectError.from(e);
        if (error.code !== Code.Unavailable) {
          this.handlers.failed(`The session ended on the server (${reason}), and a new one was refused: ${plainWords(error)}`);
          return false;
        }
        await sleep(retryMs);
      }
    }
    return false;
  }
}

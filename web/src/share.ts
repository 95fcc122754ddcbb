// Sharing a session (docs/web.md, "Sharing a session"): the owner's Share
// panel grants a user, or whoever holds a link, the role of viewer or
// presenter for a while, shows the link to hand on, and lists the session's
// grants with their revocation and the presenter's role handed over and
// taken back; and the line over the view that says who presents and how
// many watch.
import { ShareRole, type Grant } from "../gen/cinevol/v1/service_pb.js";
import type { Api } from "./api.js";
import { shareLink } from "./address.js";
import { plainWords } from "./words.js";

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

/** A grant's holder as the server names it in SessionState (presenter, pointers): the principal, or "link <id>". */
export function holder(grant: { id: string; principal: string }): string {
  return grant.principal || `link ${grant.id}`;
}

/**
 * A page's own name as the server writes it, before its pointer's echo says
 * otherwise: the owner's principal, or for a share the holder of a link (the
 * secret is "cvg_<grant id>_<key>"; a user's grant is named after the user,
 * whom the page learns from the echo).
 */
export function ownName(owner: string | undefined, grant: string): string | undefined {
  if (!grant) return owner;
  const id = /^cvg_([^_]+)_/.exec(grant)?.[1];
  return id ? `link ${id}` : undefined;
}

/**
 * The line over the view: who presents and how many watch; empty for a
 * session of one's own nobody watches. `me`: this page's name as the server
 * writes it; `shared`: this page watches by a share.
 */
export function presence(state: { presenter: string; viewers: number }, me: string | undefined, shared: boolean): string {
  const watching = `${state.viewers} ${state.viewers === 1 ? "viewer" : "viewers"}`;
  const mine = state.presenter !== "" && state.presenter === me;
  if (shared) return mine ? `You present · ${watching}` : `Watching ${state.presenter || "the owner"} · ${watching}`;
  if (state.viewers === 0) return "";
  return mine || !state.presenter || !me ? `Shared · ${watching}` : `${state.presenter} presents · ${watching}`;
}

/** How long until a grant expires, in words: "in 2 h 5 min", "in 40 s", "expired". */
export function expiresIn(expiresUnixSeconds: number, nowUnixSeconds: number): string {
  const left = Math.round(expiresUnixSeconds - nowUnixSeconds);
  if (left <= 0) return "expired";
  if (left < 60) return `in ${left} s`;
  const minutes = Math.round(left / 60), hours = Math.floor(minutes / 60), days = Math.floor(hours / 24);
  if (days >= 1) return `in ${days} d ${hours % 24} h`;
  return hours >= 1 ? `in ${hours} h ${minutes % 60} min` : `in ${minutes} min`;
}

export class SharePanel {
  private asked = 0;  // ListShares calls made: an answer older than the newest is dropped

  constructor(private readonly api: Api, private readonly sessionId: () => string | undefined,
              private readonly error: (text: string) => void) {
    $("share-create").addEventListener("click", () => void this.share());
    $("share-copy").addEventListener("click", () => void this.copy());
    $("share-take-back").addEventListener("click", () => void this.handOver(""));
    $("share").addEventListener("toggle", () => void this.refresh());
  }

  /** Offered for a session of one's own only. */
  show(on: boolean): void {
    $("share").hidden = !on;
    if (on) void this.refresh();
  }

  private async share(): Promise<void> {
    const sessionId = this.sessionId();
    if (!sessionId) return;
    const principal = $<HTMLInputElement>("share-principal").value.trim();
    const role = Number($<HTMLSelectElement>("share-role").value) as ShareRole;
    try {
      const grant = await this.api.sessions.shareSession({
        sessionId, principal, role, expiresSeconds: Number($<HTMLSelectElement>("share-expires").value),
        allowPointer: $<HTMLInputElement>("share-pointer").checked,
      });
      $<HTMLInputElement>("share-link").value = shareLink(location.origin, grant.secret);
      const until = new Date(Number(grant.expiresUnixSeconds) * 1000).toLocaleString();
      $("share-note").textContent = principal
        ? `For ${principal}: they open the link signed in with their own token. Until ${until}.`
        : `Anyone holding this link can ${role === ShareRole.PRESENTER ? "drive" : "watch"} this session until ` +
          `${until}, without a token: send it privately.`;
      $("share-result").hidden = false;
      await this.refresh();
    } catch (e) {
      this.error(plainWords(e));
    }
  }

  private async copy(): Promise<void> {
    const link = $<HTMLInputElement>("share-link");
    link.select();
    await navigator.clipboard?.writeText(link.value).catch(() => document.execCommand("copy"));
  }

  /** The session's grants (ListShares), each with its buttons. */
  async refresh(): Promise<void> {
    const sessionId = this.sessionId();
    const panel = $<HTMLDetailsElement>("share");
    if (!sessionId || panel.hidden || !panel.open) return;  // the list is seen only while the panel is open
    const call = ++this.asked;
    let grants: Grant[];
    try {
      grants = (await this.api.sessions.listShares({ sessionId })).grants;
    } catch (e) {
      return this.error(plainWords(e));
    }
    if (call !== this.asked) return;
    const now = Date.now() / 1000;
    $("share-grants").replaceChildren(...grants.map((g) => {
      const li = document.createElement("li"), name = holder(g);
      const role = g.role === ShareRole.PRESENTER ? "presenter" : "viewer";
      li.textContent = `${name} · ${role}${g.allowPointer ? " · pointer" : ""} · ` +
        `expires ${expiresIn(Number(g.expiresUnixSeconds), now)} · ${g.watching} watching `;
      li.append(this.button("Revoke", `Revoke the share of ${name}`, () => this.revoke(g.id)));
      if (g.role !== ShareRole.PRESENTER) {
        li.append(this.button("Make presenter", `Make ${name} the presenter`, () => this.handOver(g.id)));
      }
      return li;
    }));
    $<HTMLButtonElement>("share-take-back").disabled = !grants.some((g) => g.role === ShareRole.PRESENTER);
  }

  private button(text: string, label: string, click: () => Promise<void>): HTMLButtonElement {
    const b = document.createElement("button");
    b.type = "button";
    b.textContent = text;
    b.setAttribute("aria-label", label);
    b.addEventListener("click", () => void click());
    return b;
  }

  private async revoke(grantId: string): Promise<void> {
    const sessionId = this.sessionId();
    if (!sessionId) return;
    try {
      await this.api.sessions.revokeShare({ sessionId, grantId });
    } catch (e) {
      this.error(plainWords(e));
    }
    await this.refresh();
  }

  /** Makes a grant the presenter; an empty id takes the role back. */
  private async handOver(grantId: string): Promise<void> {
    const sessionId = this.sessionId();
    if (!sessionId) return;
    try {
      await this.api.sessions.handOver({ sessionId, grantId });
    } catch (e) {
      this.error(plainWords(e));
    }
    await this.refresh();
  }
}

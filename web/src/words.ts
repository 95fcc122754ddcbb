// Every refusal in plain words: what happened, then the server's own message
// (which names the field, the id or the limit).
import { Code, ConnectError } from "@connectrpc/connect";

type Leads = Partial<Record<Code, string>>;

const LEAD: Leads = {
  [Code.Unauthenticated]: "The server did not accept your token. Check it and sign in again.",
  [Code.PermissionDenied]: "That belongs to another user, or your token does not allow it.",
  [Code.NotFound]: "Not found on the server.",
  [Code.InvalidArgument]: "The server refused a value.",
  [Code.ResourceExhausted]: "The server is at one of its limits.",
  [Code.FailedPrecondition]: "Not possible in the present state.",
  [Code.Unavailable]: "The render server cannot be reached.",
  [Code.DeadlineExceeded]: "The server took too long to answer.",
  [Code.Aborted]: "This session was taken over by another window or device.",
  [Code.Unimplemented]: "This server does not offer that call (is it older than this page?).",
  [Code.Canceled]: "The call was cancelled.",
};

// What the same codes mean to someone watching by a share (#grant=): the
// server checks the grant on every call and ends its stream when it goes.
const SHARE_LEAD: Leads = {
  ...LEAD,
  [Code.PermissionDenied]: "This share has ended: its owner revoked it, or it expired. Ask them for a new link.",
  [Code.Unauthenticated]: "This share is for a named user: sign in with your own token to open it.",
  [Code.NotFound]: "The shared session no longer exists.",
  [Code.ResourceExhausted]: "The shared session has as many viewers as it may have, or the server is at one of its limits.",
};

function inWords(e: unknown, leads: Leads): string {
  const error = ConnectError.from(e);
  const lead = leads[error.code] ?? "The server failed to answer.";
  const detail = error.rawMessage.trim();
  return detail && !lead.includes(detail) ? `${lead} (${detail})` : lead;
}

export function plainWords(e: unknown): string {
  return inWords(e, LEAD);
}

/** Whether the server refused the caller's token, or asked for one. */
export function tokenRefused(e: unknown): boolean {
  return ConnectError.from(e).code === Code.Unauthenticated;
}

/**
 * Why the page asks for a token, in words: a server that needs one and was
 * sent none (its own message is for programs: send the metadata ...), or one
 * that did not accept the token sent.
 */
export function signInWords(e: unknown, sentToken: boolean): string {
  return sentToken ? plainWords(e) : "This server needs a token: enter yours in the Token field to sign in.";
}

/** A refusal to the holder of a share (a revoked or expired grant, a principal's grant without its token). */
export function shareWords(e: unknown): string {
  return inWords(e, SHARE_LEAD);
}

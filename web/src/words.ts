// Every refusal in plain words: what happened, then the server's own message
// (which names the field, the id or the limit).
import { Code, ConnectError } from "@connectrpc/connect";

const LEAD: Partial<Record<Code, string>> = {
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

export function plainWords(e: unknown): string {
  const error = ConnectError.from(e);
  const lead = LEAD[error.code] ?? "The server failed to answer.";
  const detail = error.rawMessage.trim();
  return detail && !lead.includes(detail) ? `${lead} (${detail})` : lead;
}

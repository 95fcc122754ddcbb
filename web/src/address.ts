// What the page's URL asks for (a contract: other viewers link to it):
//   /?volume=ID[&preset=P][&fuse=ID2[&align=patient]][&session=S]#token=T
//                                     fuse: a second volume over the first (PET on CT); align=patient places one of
//                                     another frame of reference by its patient coordinates (docs/web.md)
//   /#grant=SECRET[&token=T]          a shared session (docs/web.md, "Sharing a session")
//   /iid?requestType=STUDY&studyUID=UID#token=T   an IHE IID launch (iid.ts)
// The token and a grant's secret ride in the fragment, so they never reach a
// server log, a proxy or a Referer; the page takes them out of the address
// bar once read.

import { IID_PATHS, readIid, type IidRequest } from "./iid.js";

export interface PageAddress {
  volume?: string;
  preset?: string;
  fuse?: string;            // a second volume fused with the first
  alignByPatient?: boolean;  // align=patient: fused though their frames of reference differ
  session?: string;  // join an existing session of one's own (a reload resumes it)
  token?: string;
  grant?: string;    // a share's secret: watch (or present) the session it names
  iid?: IidRequest;  // an IID launch: the study (or the patient's latest) to open from the PACS
}

export function readAddress(search: string, hash: string, pathname = "/"): PageAddress {
  const query = new URLSearchParams(search);
  const fragment = new URLSearchParams(hash.replace(/^#/, ""));
  const pick = (p: URLSearchParams, key: string) => p.get(key)?.trim() || undefined;
  const iid = IID_PATHS.includes(pathname) ? readIid(query) : undefined;  // the gateway refused a malformed one
  return { volume: pick(query, "volume"), preset: pick(query, "preset"), fuse: pick(query, "fuse"),
           alignByPatient: pick(query, "align") === "patient", session: pick(query, "session"),
           token: pick(fragment, "token"), grant: pick(fragment, "grant"),
           iid: typeof iid === "object" ? iid : undefined };
}

/** The address to show once the token or grant is read: the same query, no fragment. */
export function withoutToken(pathname: string, search: string): string {
  return pathname + search;
}

/** The query for a session: reloading the page resumes it. */
export function sessionQuery(search: string, sessionId: string): string {
  const query = new URLSearchParams(search);
  query.set("session", sessionId);
  return "?" + query.toString();
}

/** The link a share's holder opens: the secret in the fragment, as the token is. */
export function shareLink(origin: string, secret: string): string {
  return `${origin}/#grant=${encodeURIComponent(secret)}`;
}

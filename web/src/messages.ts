// What the line over the 3D view says: one message at a time, so that an
// error never stands beside "waiting for the first frame" or a notice that
// came before it.

export interface Messages {
  error: string;    // what went wrong: shown until it is cleared
  banner: string;   // news: the connection, a notice, a series loading
  waiting: string;  // what the page waits for while nothing else is said ("" once a frame shows)
}

export interface Shown {
  kind: "error" | "banner";  // the element it goes to: an alert, or a polite status
  text: string;
}

/** The one message to show: an error before news, news before waiting; null when there is nothing to say. */
export function messageToShow(m: Messages): Shown | null {
  if (m.error) return { kind: "error", text: m.error };
  const text = m.banner || m.waiting;
  return text ? { kind: "banner", text } : null;
}

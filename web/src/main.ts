// The page's entry: read the address (?volume=ID&preset=P#token=T, or a
// shared session's #grant=SECRET), sign in, and hand over to the App. The
// token and the grant leave the address bar at once and stay in this tab's
// session storage, so a reload resumes.
import { connect } from "./api.js";
import { readAddress, withoutToken, type PageAddress } from "./address.js";
import { App } from "./app.js";
import { plainWords, signInWords, tokenRefused } from "./words.js";

const TOKEN_KEY = "cinevol-token";
const GRANT_KEY = "cinevol-grant";
const HOLD_LOAD_MS = 30_000;

/**
 * Keeps the page's load event back until `done` settles (at most
 * HOLD_LOAD_MS): a child document left open holds its parent's load. So the
 * page counts as loaded once it shows the volume, and tools that capture a
 * page at its load (`chromium --headless --screenshot`, thumbnailers) see it.
 */
function holdLoadUntil(done: Promise<unknown>): void {
  const hold = document.createElement("iframe");
  hold.hidden = true;
  hold.title = "loading";
  document.body.append(hold);
  hold.contentDocument?.open();
  const release = () => hold.contentDocument?.close();
  void Promise.race([done, new Promise((r) => setTimeout(r, HOLD_LOAD_MS))]).finally(release);
}

/**
 * One App for the page: with a token (one's own sessions, or a user's share)
 * or none (a server that needs none, or a link's share). A server that wants
 * a token says so, and the page asks for it in words.
 */
async function start(token: string | undefined, address: PageAddress): Promise<void> {
  const app = new App(connect(token, location.origin));
  (window as unknown as { cinevol: unknown }).cinevol = {
    status: () => app.status(),
    sample: (cells?: number) => app.view.sample(cells),
  };
  holdLoadUntil(app.firstPaint);
  app.onTokenRefused = () => {  // a user's share opened without (or with a wrong) token
    sessionStorage.removeItem(TOKEN_KEY);
    askForToken();
  };
  try {
    await app.boot(address);
  } catch (e) {
    if (!tokenRefused(e)) return app.showError(plainWords(e));
    app.showError(signInWords(e, token !== undefined));
    app.onTokenRefused();
  }
}

function askForToken(): void {
  const form = document.getElementById("sign-in") as HTMLFormElement;
  form.hidden = false;
  form.onsubmit = (e) => {
    e.preventDefault();
    const token = (document.getElementById("token") as HTMLInputElement).value.trim();
    if (!token) return;
    sessionStorage.setItem(TOKEN_KEY, token);
    location.reload();  // one App per page: a fresh start with the new token
  };
  document.getElementById("token")!.focus();
}

const address = readAddress(location.search, location.hash, location.pathname);
if (address.token) sessionStorage.setItem(TOKEN_KEY, address.token);
if (address.grant) sessionStorage.setItem(GRANT_KEY, address.grant);
if (address.token || address.grant) history.replaceState(null, "", withoutToken(location.pathname, location.search));
const token = sessionStorage.getItem(TOKEN_KEY) ?? undefined;
// A share is watched again on a reload, unless the query names a volume or session of one's own.
const grant = address.grant ?? (address.volume || address.session ? undefined : sessionStorage.getItem(GRANT_KEY) ?? undefined);
// Without a token too: a server that needs none opens at once, one that does says so (start above).
void start(token, { ...address, grant });

// The page's entry: read the address (?volume=ID&preset=P#token=T), sign in,
// and hand over to the App. The token leaves the address bar at once and
// stays in this tab's session storage, so a reload resumes.
import { connect } from "./api.js";
import { readAddress, withoutToken } from "./address.js";
import { App } from "./app.js";
import { plainWords } from "./words.js";

const TOKEN_KEY = "cinevol-token";
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

async function signIn(token: string): Promise<void> {
  const app = new App(connect(token, location.origin));
  (window as unknown as { cinevol: unknown }).cinevol = {
    status: () => app.status(),
    sample: (cells?: number) => app.view.sample(cells),
  };
  holdLoadUntil(app.firstPaint);
  try {
    await app.boot(readAddress(location.search, ""));
  } catch (e) {
    app.showError(plainWords(e));
    sessionStorage.removeItem(TOKEN_KEY);
    askForToken();
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
}

const address = readAddress(location.search, location.hash);
if (address.token) {
  sessionStorage.setItem(TOKEN_KEY, address.token);
  history.replaceState(null, "", withoutToken(location.pathname, location.search));
}
const token = sessionStorage.getItem(TOKEN_KEY);
if (token) void signIn(token);
else askForToken();

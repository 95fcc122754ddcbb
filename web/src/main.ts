// The page's entry: read the address (?volume=ID&preset=P#token=T), sign in,
// and hand over to the App. The token leaves the address bar at once and
// stays in this tab's session storage, so a reload resumes.
import { connect } from "./api.js";
import { readAddress, withoutToken } from "./address.js";
import { App } from "./app.js";
import { plainWords } from "./words.js";

const TOKEN_KEY = "cinevol-token";

async function signIn(token: string): Promise<void> {
  const app = new App(connect(token, location.origin));
  (window as unknown as { cinevol: unknown }).cinevol = {
    status: () => app.status(),
    sample: (cells?: number) => app.view.sample(cells),
  };
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

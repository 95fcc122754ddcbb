// The page served by the stack's cinevol-web, in Debian's headless chromium from outside the
// stack (playwright-core from web/node_modules, never a downloaded browser): it opens the
// page's address, waits for painted frames, and saves a screenshot. Only the stack's own
// certificate is trusted beyond the system's (--spki: its public key's SHA-256, base64).
//
//   NODE_PATH=web/node_modules node screenshot.mjs --url 'https://127.0.0.1:PORT/?volume=ID#token=T' \
//     --spki HASH --out page.png [--timeout 120]
import { createRequire } from "node:module";
import { join } from "node:path";
import { parseArgs } from "node:util";

const { values: args } = parseArgs({ options: {
  url: { type: "string" }, spki: { type: "string" }, out: { type: "string" }, timeout: { type: "string", default: "120" },
} });
for (const k of ["url", "spki", "out"]) if (!args[k]) throw new Error(`--${k} is required`);
const url = new URL(args.url);
if (url.protocol !== "https:" || url.hostname !== "127.0.0.1") throw new Error(`--url must be https://127.0.0.1:...`);
const require = createRequire(join(process.env.NODE_PATH ?? ".", "noop.js"));
const { chromium } = require("playwright-core");
const timeout = Number(args.timeout) * 1000;

// As web/e2e does: no background networking, no sandbox as root.
const browser = await chromium.launch({
  executablePath: process.env.CINEVOL_CHROMIUM ?? "/usr/bin/chromium", timeout: 60_000,
  args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", `--ignore-certificate-errors-spki-list=${args.spki}`],
});
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  const started = Date.now();
  await page.goto(args.url, { timeout });
  // The page's own status (web/src/app.ts): frames painted on its canvas.
  await page.waitForFunction(() => (globalThis.cinevol?.status?.().framesPainted ?? 0) >= 3, undefined,
                             { timeout, polling: 200 });
  const status = await page.evaluate(() => globalThis.cinevol.status());
  await page.screenshot({ path: args.out });
  console.log(`page: ${status.framesPainted} frames painted ${Date.now() - started} ms after it was opened; ` +
              `session ${status.sessionId}; screenshot ${args.out}`);
} finally {
  await browser.close();
}

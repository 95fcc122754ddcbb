// The browser's live view, measured in the page (bench/cpu-view-run.sh's
// `browser` part; docs/web.md): a session made from SCENE through cinevol-web
// (CreateSession in the Connect protocol, as any script can), then Debian's
// headless chromium showing it at 1280x720 CSS pixels (the page's 320-pixel
// panel beside) while the mouse drags an orbit of 360 degrees in SECONDS at
// 30 moves a second. Prints the page's own figures: frames painted a second,
// motion-to-photon (the pointer event to the frame drawn that answers it)
// p50/p95, bytes received a second.
//   node bench/web-view.mjs --gateway 127.0.0.1:PORT --volume ID --scene S.json [--stream JSON] [--seconds 20]
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";
import { parseArgs } from "node:util";

const require = createRequire(new URL("../web/package.json", import.meta.url));
const { chromium } = require("playwright-core");
const { values: o } = parseArgs({ options: {
  gateway: { type: "string" }, volume: { type: "string" }, scene: { type: "string" },
  stream: { type: "string", default: "{}" }, seconds: { type: "string", default: "20" },
  chromium: { type: "string", default: "/usr/bin/chromium" }, screenshot: { type: "string" },
} });
const base = `http://${o.gateway}`, seconds = Number(o.seconds);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

const scene = JSON.parse(readFileSync(o.scene, "utf8"));
delete scene.volume;  // volumeId says which
const created = await fetch(`${base}/cinevol.v1.SessionService/CreateSession`, {
  method: "POST", headers: { "content-type": "application/json" },
  body: JSON.stringify({ volumeId: o.volume, viewport: { width: 1280, height: 720 }, scene,
                         stream: JSON.parse(o.stream) }),
});
if (!created.ok) throw new Error(`CreateSession: ${created.status} ${await created.text()}`);
const { sessionId } = await created.json();

const browser = await chromium.launch({ executablePath: o.chromium, args: ["--no-sandbox", "--disable-gpu",
  "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update",
  "--disable-sync"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280 + 320, height: 720 } });
  await page.goto(`${base}/?session=${sessionId}#token=local`);
  const status = () => page.evaluate(() => window.cinevol.status());
  await page.waitForFunction(() => window.cinevol?.status().framesPainted >= 2, null, { timeout: 120_000 });
  const box = await page.locator("#view").boundingBox();
  const moves = Math.round(seconds * 30), step = 900 / moves;  // 900 pixels at 0.4 degrees a pixel: 360 degrees
  let x = box.x + box.width / 2 - 450;
  const y = box.y + box.height / 2;
  await page.mouse.move(x, y);
  await page.mouse.down();
  const start = Date.now();
  for (let i = 1; i <= moves; ++i) {
    x += step;
    await page.mouse.move(x, y);
    await sleep(Math.max(0, start + (i * 1000) / 30 - Date.now()));
  }
  const s = await status();
  await page.mouse.up();
  if (o.screenshot) await page.screenshot({ path: o.screenshot });
  const f = s.lastFrame;
  console.log(`browser: ${s.fps.toFixed(1)} fps painted, motion-to-photon p50/p95 ${s.motionToPhoton.p50.toFixed(0)}/` +
              `${s.motionToPhoton.p95.toFixed(0)} ms over ${s.motionToPhoton.count} events, ` +
              `${(s.bytesPerSecond / 1e6).toFixed(2)} MB/s, decode and draw p50/p95 ${s.decodeMs.p50.toFixed(1)}/` +
              `${s.decodeMs.p95.toFixed(1)} ms (worker), last frame ${f.width}x${f.height}` +
              (s.error ? `, error: ${s.error}` : ""));
} finally {
  await browser.close();
}

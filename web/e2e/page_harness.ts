// What the page's end-to-end tests share (page.test.ts runs them): Debian's
// headless chromium (driven by playwright-core, never a downloaded browser),
// a real cinevol-server (CPU) and cinevol-web on free loopback ports, the
// page's status as tests read it, and the waits and drags they use.
// Exits 77 (skipped) without chromium.
import { existsSync, mkdirSync } from "node:fs";
import { join } from "node:path";
import { chromium, type Browser, type Page } from "playwright-core";
import { scratch, startWithPortFile, stop, tokensFile, type Running } from "./processes.js";
import { writeMovingBallNrrd, writeSphereNrrd } from "./sphere.js";

export const CHROMIUM = process.env.CINEVOL_CHROMIUM ?? "/usr/bin/chromium";
if (!existsSync(CHROMIUM)) {
  console.log(`skipped: no chromium at ${CHROMIUM} (scripts/install-deps.sh installs Debian's)`);
  process.exit(77);
}
export const SERVER = process.env.CINEVOL_SERVER!, WEB = process.env.CINEVOL_WEB!;
export const ARTIFACTS = process.env.CINEVOL_ARTIFACTS ?? join(scratch, "artifacts");
mkdirSync(ARTIFACTS, { recursive: true });
// As the environment's notes say: no background networking (this machine's network is closed), no sandbox as root.
export const CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
  "--disable-background-networking", "--disable-component-update", "--disable-sync"];
export const WAIT = { timeout: 90_000, polling: 100 };
// A DICOM series with a patient and study (the identity step skips without it).
export const MR_DICOM = join(process.env.CINEVOL_SHARED_DATA ?? "", "mr-chest-dicom-seg3d");

/** What the tests share, set up before the first: the servers, gateways, the browser and alice's page. */
export const run = {} as {
  server: Running; gateway: Running; browser: Browser; alice: Page;
  openServer: Running; openGateway: Running;  // a server that needs no token, holding the spheres and the ball below
};
export const base = () => `http://127.0.0.1:${run.gateway.port}`;
// A sphere of 20 mm radius in voxels of 0.8 x 0.8 x 2 mm: 72 x 72 x 32 of them span 56.8 x 56.8 x 62 mm.
export const SPHERE = { dims: [72, 72, 32], spacingMm: [0.8, 0.8, 2], radiusMm: 20 } as const;

export interface PageStatus {
  sessionId: string; eventsSent: number; messages: string[]; framesPainted: number; error: string; banner: string; preset: string;
  lastFrame: { id: number; lastEventSeq: number; width: number; height: number } | null;
  motionToPhoton: { count: number };
  eventsByKind: Record<string, number>; frameIds: number[]; presenter: string; viewers: number; driving: boolean;
  pointers: { who: string; x: number; y: number }[];
  camera: { eye: V; target: V; up: V } | null;  // the camera the page drags from (the state's, or its own newer one)
}
export type V = { x: number; y: number; z: number };
export const status = (page: Page) => page.evaluate(() => (window as any).cinevol.status()) as Promise<PageStatus>;
export const sample = (page: Page) => page.evaluate(() => (window as any).cinevol.sample(16)) as
  Promise<{ width: number; height: number; grid: number[] }>;
export const meanDifference = (a: number[], b: number[]) => a.reduce((s, v, i) => s + Math.abs(v - b[i]), 0) / a.length;
export const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

/** Waits until the element's text matches; on timeout says what it showed instead. */
export async function waitForText(page: Page, selector: string, pattern: RegExp): Promise<string> {
  try {
    await page.waitForFunction(([sel, source]) => new RegExp(source).test(document.querySelector(sel)!.textContent!),
                               [selector, pattern.source] as const, WAIT);
  } catch (e) {
    throw new Error(`${selector} never matched ${pattern}: it shows "${await page.textContent(selector)}", ` +
                    `the error line "${await page.textContent("#error")}" (${e})`);
  }
  return (await page.textContent(selector)) ?? "";
}

/** The messages over the view that can be seen: one at most (an error never beside a banner or "waiting"). */
export async function messagesShown(page: Page): Promise<string[]> {
  const shown = await page.$$eval("#banner, #error", (lines) => lines.filter((l) => l.getClientRects().length > 0)
    .map((l) => l.textContent ?? ""));
  const stats = await page.textContent("#stats") ?? "";
  return /waiting/i.test(stats) ? [...shown, stats] : shown;
}

/** Waits for `count` more frames painted than now. */
export async function framesAfter(page: Page, count: number): Promise<void> {
  const painted = (await status(page)).framesPainted;
  await page.waitForFunction((n) => (window as any).cinevol.status().framesPainted >= n, painted + count, WAIT);
}

/** Waits until the page's status meets `done` (polled from here); on timeout says what the status was. */
export async function until(page: Page, done: (s: PageStatus) => boolean, what: string): Promise<PageStatus> {
  let s = await status(page);
  for (const end = Date.now() + WAIT.timeout; !done(s); s = await status(page)) {
    if (Date.now() > end) throw new Error(`${what}: never came; the page says ${JSON.stringify(s)}`);
    await sleep(WAIT.polling);
  }
  return s;
}

/** Drags across the middle of the 3D view. */
export async function drag(page: Page, dx: number, dy: number): Promise<void> {
  const box = (await page.locator("#view").boundingBox())!;
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + dx, box.y + box.height / 2 + dy, { steps: 10 });
  await page.mouse.up();
}

/** Waits until a frame answering every event sent so far has been painted, then a couple more. */
export async function settled(page: Page): Promise<void> {
  await page.waitForFunction(() => {
    const s = (window as any).cinevol.status();
    return s.eventsSent > 0 && s.lastFrame && s.lastFrame.lastEventSeq >= s.eventsSent;
  }, null, WAIT);
  await framesAfter(page, 2);
}

/** Sets the page's window (700 pixels wide or more: narrower, the panel goes below) and waits for a frame as wide as
 *  its canvas, the window less the 320-pixel panel: a movie renders the session's size, and the CPU's movie frames of
 *  a 640x540 canvas took about a second each. */
export async function resizeWindow(page: Page, width: number, height: number): Promise<void> {
  await page.setViewportSize({ width, height });
  await page.waitForFunction((w) => (window as any).cinevol.status().lastFrame?.width === w, width - 320, WAIT);
}

export async function startGateway(port = 0): Promise<Running> {
  return startWithPortFile(WEB, ["--listen", `127.0.0.1:${port}`, "--server", `127.0.0.1:${run.server.port}`], "gateway");
}

/** The servers (one with two principals' tokens, one open with the sphere), their gateways, chromium, alice's page. */
export async function setUp(): Promise<void> {
  const tokens = tokensFile("alice-token alice\nbob-token bob\n");
  const dicom = existsSync(MR_DICOM) ? ["--volume", "phantom:head", "--volume", MR_DICOM] : [];
  run.server = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu", "--auth-tokens", tokens,
                                                ...dicom], "server");
  run.gateway = await startGateway();
  const sphere = join(scratch, "sphere.nrrd");
  writeSphereNrrd(sphere, [...SPHERE.dims], [...SPHERE.spacingMm], SPHERE.radiusMm);
  const beat = join(scratch, "beat.nrrd");
  writeMovingBallNrrd(beat, 32, 4, 6, 0.05);
  const hot = join(scratch, "hot.nrrd");  // a larger sphere on the same grid, a halo round the first: a volume to fuse
  writeSphereNrrd(hot, [...SPHERE.dims], [...SPHERE.spacingMm], SPHERE.radiusMm * 1.4);
  run.openServer = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu", "--volume", sphere,
                                                    "--volume", beat, "--volume", hot], "open-server");
  run.openGateway = await startWithPortFile(WEB, ["--listen", "127.0.0.1:0", "--server",
                                                  `127.0.0.1:${run.openServer.port}`], "open-gateway");
  run.browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 60_000 });
  run.alice = await run.browser.newPage({ viewport: { width: 960, height: 540 } });
}

export async function tearDown(): Promise<void> {
  await run.browser?.close().catch(() => {});
  await stop(run.gateway);
  await stop(run.server);
  await stop(run.openGateway);
  await stop(run.openServer);
}


// The page in Debian's headless chromium (driven by playwright-core, never a
// downloaded browser) against a real cinevol-server (CPU) and cinevol-web on
// free loopback ports. Screenshots go to $CINEVOL_ARTIFACTS.
// Run directly (node page.test.mjs): exit 77 (skipped) without chromium.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { request } from "node:https";
import { existsSync, mkdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { after, before, test } from "node:test";
import { chromium, type Browser, type Page } from "playwright-core";
import { decodePng } from "./png.js";
import { scratch, startWithPortFile, stop, tokensFile, type Running } from "./processes.js";
import { crosshairOn, discOn, writeSphereNrrd } from "./sphere.js";

const CHROMIUM = process.env.CINEVOL_CHROMIUM ?? "/usr/bin/chromium";
if (!existsSync(CHROMIUM)) {
  console.log(`skipped: no chromium at ${CHROMIUM} (scripts/install-deps.sh installs Debian's)`);
  process.exit(77);
}
const SERVER = process.env.CINEVOL_SERVER!, WEB = process.env.CINEVOL_WEB!;
const ARTIFACTS = process.env.CINEVOL_ARTIFACTS ?? join(scratch, "artifacts");
mkdirSync(ARTIFACTS, { recursive: true });
// As the environment's notes say: no background networking (this machine's network is closed), no sandbox as root.
const CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
  "--disable-background-networking", "--disable-component-update", "--disable-sync"];
const WAIT = { timeout: 90_000, polling: 100 };
// A DICOM series with a patient and study (the identity step skips without it).
const MR_DICOM = join(process.env.CINEVOL_SHARED_DATA ?? "", "mr-chest-dicom-seg3d");

let server: Running, gateway: Running, browser: Browser, alice: Page;
let openServer: Running, openGateway: Running;  // a server that needs no token, holding only the sphere below
const base = () => `http://127.0.0.1:${gateway.port}`;
// A sphere of 20 mm radius in voxels of 0.8 x 0.8 x 2 mm: 72 x 72 x 32 of them span 56.8 x 56.8 x 62 mm.
const SPHERE = { dims: [72, 72, 32], spacingMm: [0.8, 0.8, 2], radiusMm: 20 } as const;

interface PageStatus {
  sessionId: string; eventsSent: number; messages: string[]; framesPainted: number; error: string; banner: string; preset: string;
  lastFrame: { id: number; lastEventSeq: number; width: number; height: number } | null;
  motionToPhoton: { count: number };
  eventsByKind: Record<string, number>; frameIds: number[]; presenter: string; viewers: number; driving: boolean;
  pointers: { who: string; x: number; y: number }[];
  camera: { eye: V; target: V; up: V } | null;  // the camera the page drags from (the state's, or its own newer one)
}
type V = { x: number; y: number; z: number };
const status = (page: Page) => page.evaluate(() => (window as any).cinevol.status()) as Promise<PageStatus>;
const sample = (page: Page) => page.evaluate(() => (window as any).cinevol.sample(16)) as
  Promise<{ width: number; height: number; grid: number[] }>;
const meanDifference = (a: number[], b: number[]) => a.reduce((s, v, i) => s + Math.abs(v - b[i]), 0) / a.length;
const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

/** Waits until the element's text matches; on timeout says what it showed instead. */
async function waitForText(page: Page, selector: string, pattern: RegExp): Promise<string> {
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
async function messagesShown(page: Page): Promise<string[]> {
  const shown = await page.$$eval("#banner, #error", (lines) => lines.filter((l) => l.getClientRects().length > 0)
    .map((l) => l.textContent ?? ""));
  const stats = await page.textContent("#stats") ?? "";
  return /waiting/i.test(stats) ? [...shown, stats] : shown;
}

/** Waits for `count` more frames painted than now. */
async function framesAfter(page: Page, count: number): Promise<void> {
  const painted = (await status(page)).framesPainted;
  await page.waitForFunction((n) => (window as any).cinevol.status().framesPainted >= n, painted + count, WAIT);
}

/** Waits until the page's status meets `done` (polled from here); on timeout says what the status was. */
async function until(page: Page, done: (s: PageStatus) => boolean, what: string): Promise<PageStatus> {
  let s = await status(page);
  for (const end = Date.now() + WAIT.timeout; !done(s); s = await status(page)) {
    if (Date.now() > end) throw new Error(`${what}: never came; the page says ${JSON.stringify(s)}`);
    await sleep(WAIT.polling);
  }
  return s;
}

/** Drags across the middle of the 3D view. */
async function drag(page: Page, dx: number, dy: number): Promise<void> {
  const box = (await page.locator("#view").boundingBox())!;
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + dx, box.y + box.height / 2 + dy, { steps: 10 });
  await page.mouse.up();
}

/** Waits until a frame answering every event sent so far has been painted, then a couple more. */
async function settled(page: Page): Promise<void> {
  await page.waitForFunction(() => {
    const s = (window as any).cinevol.status();
    return s.eventsSent > 0 && s.lastFrame && s.lastFrame.lastEventSeq >= s.eventsSent;
  }, null, WAIT);
  await framesAfter(page, 2);
}

async function startGateway(port = 0): Promise<Running> {
  return startWithPortFile(WEB, ["--listen", `127.0.0.1:${port}`, "--server", `127.0.0.1:${server.port}`], "gateway");
}

before(async () => {
  const tokens = tokensFile("alice-token alice\nbob-token bob\n");
  const dicom = existsSync(MR_DICOM) ? ["--volume", "phantom:head", "--volume", MR_DICOM] : [];
  server = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu", "--auth-tokens", tokens,
                                            ...dicom], "server");
  gateway = await startGateway();
  const sphere = join(scratch, "sphere.nrrd");
  writeSphereNrrd(sphere, [...SPHERE.dims], [...SPHERE.spacingMm], SPHERE.radiusMm);
  openServer = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu", "--volume", sphere],
                                       "open-server");
  openGateway = await startWithPortFile(WEB, ["--listen", "127.0.0.1:0", "--server", `127.0.0.1:${openServer.port}`],
                                        "open-gateway");
  browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 60_000 });
  alice = await browser.newPage({ viewport: { width: 960, height: 540 } });
});

after(async () => {
  await browser?.close().catch(() => {});
  await stop(gateway);
  await stop(server);
  await stop(openGateway);
  await stop(openServer);
});

test("the page opens from its URL, signs in from the fragment and streams at the canvas's size", async () => {
  await alice.goto(`${base()}/?volume=phantom:head#token=alice-token`);
  await alice.waitForFunction(() => (window as any).cinevol?.status().framesPainted >= 3, null, WAIT);
  assert.ok(!alice.url().includes("token"), "the token leaves the address bar");
  const s = await status(alice);
  const canvas = await alice.evaluate(() => {
    const r = document.getElementById("view")!.getBoundingClientRect();
    return { width: Math.round(r.width * devicePixelRatio), height: Math.round(r.height * devicePixelRatio) };
  });
  assert.deepEqual({ width: s.lastFrame!.width, height: s.lastFrame!.height }, canvas);
  assert.equal(s.error, "");
  assert.equal(await alice.inputValue("#volumes"), "phantom:head", "the volume list shows the volume open");
  assert.ok((await messagesShown(alice)).length <= 1, JSON.stringify(await messagesShown(alice)));
  await alice.screenshot({ path: join(ARTIFACTS, "1-streams.png") });
});

test("an orbit drag changes the picture", async () => {
  await framesAfter(alice, 3);
  const still = [await sample(alice), await (framesAfter(alice, 1).then(() => sample(alice)))];
  const noise = meanDifference(still[0].grid, still[1].grid);
  const box = (await alice.locator("#view").boundingBox())!;
  await alice.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await alice.mouse.down();
  await alice.mouse.move(box.x + box.width / 2 + 200, box.y + box.height / 2 + 40, { steps: 10 });
  await alice.mouse.up();
  await settled(alice);
  const turned = await sample(alice);
  const change = meanDifference(still[1].grid, turned.grid);
  assert.ok(change > 3 * noise + 2, `orbit changed the picture by ${change.toFixed(2)} (frame to frame: ${noise.toFixed(2)})`);
  await alice.screenshot({ path: join(ARTIFACTS, "2-orbited.png") });
});

test("a named view turns about the current target at the current distance, on the server (A P L R S I)", async () => {
  const box = (await alice.locator("#view").boundingBox())!;
  await alice.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await alice.mouse.wheel(0, 100);  // a step back first: the view keeps the distance it finds
  await settled(alice);
  const before = (await status(alice)).camera!;
  await alice.keyboard.press("l");
  const turned = await until(alice, (s) => s.camera !== null && Math.abs(s.camera.eye.x - before.eye.x) > 1,
                             "the left view's camera in the state");
  const c = turned.camera!, distance = (k: typeof c) => Math.hypot(k.eye.x - k.target.x, k.eye.y - k.target.y,
                                                                   k.eye.z - k.target.z);
  assert.ok(Math.abs(distance(c) - distance(before)) < 1e-3 * distance(before),
            `the distance went from ${distance(before)} to ${distance(c)}`);
  for (const k of ["x", "y", "z"] as const) assert.ok(Math.abs(c.target[k] - before.target[k]) < 1e-3, `target.${k}`);
  // The phantom lies in LPS: the left view looks from the patient's left (+x), head up.
  assert.ok((c.eye.x - c.target.x) / distance(c) > 0.999, JSON.stringify(c));
  assert.ok(c.up.z > 0.999, JSON.stringify(c));
  assert.equal((await status(alice)).error, "");
  await settled(alice);
});

test("a preset changes the picture", async () => {
  const before = await sample(alice);
  const current = (await status(alice)).preset;
  const options = await alice.$$eval("#preset option", (o) => o.map((x) => (x as HTMLOptionElement).value));
  const other = options.find((p) => p && p !== current && p.startsWith("ct-"))!;
  await alice.selectOption("#preset", other);
  await alice.waitForFunction((p) => (window as any).cinevol.status().preset === p, other, WAIT);
  await settled(alice);
  const after = await sample(alice);
  assert.ok(meanDifference(before.grid, after.grid) > 2, `preset ${other} left the picture as it was`);
  await alice.screenshot({ path: join(ARTIFACTS, "3-preset.png") });
});

test("a window resize changes the frame's size", async () => {
  const before = (await status(alice)).lastFrame!;
  await alice.setViewportSize({ width: 720, height: 620 });
  await alice.waitForFunction((w) => (window as any).cinevol.status().lastFrame.width !== w, before.width, WAIT);
  const after = (await status(alice)).lastFrame!;
  assert.equal(after.width, 720 - 320, "the canvas is the window less the 320-pixel panel");
  assert.ok(after.height > before.height);
  await alice.screenshot({ path: join(ARTIFACTS, "4-resized.png") });
});

test("reading: slices beside the 3D view, a pick, a distance measured on a slice", async () => {
  await alice.click("#layout");
  await alice.waitForFunction(() => [...document.querySelectorAll<HTMLImageElement>(".slice img")]
    .every((img) => img.naturalWidth > 0), null, WAIT);
  const edges = await alice.$$eval("#slice-axial [class^=edge-]", (e) => e.map((x) => x.textContent));
  assert.deepEqual(edges, ["R", "L", "A", "P"], "axial slices in radiological convention");
  const axial = await alice.$eval("#slice-axial img", (img) => ({ w: (img as HTMLImageElement).naturalWidth,
                                                                  h: (img as HTMLImageElement).naturalHeight }));
  assert.deepEqual(axial, { w: 256, h: 256 }, "one pixel a voxel of the 256^3 phantom");
  const planeColours = await alice.$eval("#view-overlay", (c) => {
    const canvas = c as HTMLCanvasElement, { data } = canvas.getContext("2d")!.getImageData(0, 0, canvas.width, canvas.height);
    const seen = { red: 0, green: 0, yellow: 0 };
    for (let i = 0; i < data.length; i += 4) {
      const [r, g, b, a] = [data[i], data[i + 1], data[i + 2], data[i + 3]];
      if (a < 200 || b > 100) continue;
      if (r > 200 && g < 100) seen.red++; else if (r < 100 && g > 170) seen.green++; else if (r > 200 && g > 170) seen.yellow++;
    }
    return seen;
  });
  assert.ok(planeColours.red > 20 && planeColours.green > 20 && planeColours.yellow > 20,
            `the three slice planes outlined on the 3D view: ${JSON.stringify(planeColours)}`);
  const view = (await alice.locator("#view").boundingBox())!;
  await alice.mouse.click(view.x + view.width / 2, view.y + view.height / 2);
  await waitForText(alice, "#pick-info", /HU/);
  await alice.click("#measure-distance");
  const slice = (await alice.locator("#slice-axial img").boundingBox())!;
  const side = Math.min(slice.width, slice.height);
  await alice.mouse.click(slice.x + slice.width / 2 - side / 4, slice.y + slice.height / 2);
  await alice.mouse.click(slice.x + slice.width / 2 + side / 4, slice.y + slice.height / 2);
  const text = await waitForText(alice, "#measurements", /Distance \d+\.\d mm/);
  const mm = Number(/Distance (\d+\.\d) mm/.exec(text)![1]);
  assert.ok(Math.abs(mm - 128) < 3, `half the 256 mm slice's width: ${mm} mm`);
  await alice.screenshot({ path: join(ARTIFACTS, "5-reading.png") });
  await alice.click("#layout");
});

test("a DICOM volume's patient and study show in the corners until F4 hides them", async (t) => {
  if (!existsSync(MR_DICOM)) return t.skip(`no shared data at ${MR_DICOM}`);
  const page = await browser.newPage({ viewport: { width: 800, height: 450 } });
  // Not waiting for the load (held until the first frame): the banner says what the page waits for until then, and
  // then the server's notice for a few seconds, below the corners, never over them.
  await page.goto(`${base()}/?volume=mr-chest-dicom-seg3d#token=alice-token`, { waitUntil: "domcontentloaded" });
  await page.waitForFunction(() => ["identity", "banner"].every((id) => document.getElementById(id)!.getClientRects().length),
                             null, WAIT);
  const boxes = await page.$$eval("#identity-top-left, #identity-top-right, #banner", (e) => e.map((x) => x.getBoundingClientRect()));
  const [topLeft, topRight, banner] = boxes.map((b) => ({ left: b.left, right: b.right, top: b.top, bottom: b.bottom }));
  for (const corner of [topLeft, topRight]) {
    const overlaps = corner.left < banner.right && banner.left < corner.right && corner.top < banner.bottom &&
                     banner.top < corner.bottom;
    assert.ok(!overlaps, `the banner ${JSON.stringify(banner)} covers a patient corner ${JSON.stringify(corner)}`);
  }
  await page.waitForFunction(() => (window as any).cinevol?.status().framesPainted >= 1, null, WAIT);
  assert.ok(await page.isVisible("#identity"), "shown by default");
  assert.equal(await page.textContent("#identity-top-left"), "My Patient Name\nID 123456789");
  assert.equal(await page.textContent("#identity-top-right"),
               "2009-12-03\nMy Study Name\nMy Special Series For Testing");
  assert.ok(await page.$("#window-preset option[value=stored]"), "the DICOM's own window is offered");
  await page.screenshot({ path: join(ARTIFACTS, "5-identity.png") });
  await page.keyboard.press("F3");  // in the 2x2 they keep to the 3D view's corners
  const [view, right] = await page.$$eval("#view, #identity-top-right", (e) => e.map((x) => x.getBoundingClientRect().right));
  assert.ok(right <= view && view - right < 20, `the study's corner ends at ${right}, the 3D view at ${view}`);
  await page.screenshot({ path: join(ARTIFACTS, "5-identity-2x2.png") });
  await page.keyboard.press("F3");
  await page.keyboard.press("F4");
  assert.ok(!(await page.isVisible("#identity")), "F4 hides them");
  await page.close();
  // The phantom has none: nothing in the corners.
  assert.ok(!(await alice.isVisible("#identity")));
});

test("a wrong token is refused with a message on the page", async () => {
  const page = await browser.newPage();
  await page.goto(`${base()}/?volume=phantom:head#token=wrong-token`);
  await page.waitForFunction(() => document.getElementById("error")!.textContent!.length > 0, null, WAIT);
  assert.match(await page.textContent("#error") ?? "", /did not accept your token/);
  assert.ok(await page.isVisible("#sign-in"), "the sign-in form is offered again");
  assert.deepEqual(await messagesShown(page), [await page.textContent("#error")], "the error alone, no waiting beside it");
  await page.screenshot({ path: join(ARTIFACTS, "5-wrong-token.png") });
  await page.close();
});

test("a server that needs a token says so beside a sign-in field, and streams once it is entered", async () => {
  const page = await browser.newPage({ viewport: { width: 800, height: 450 } });
  await page.goto(`${base()}/?volume=phantom:head`);
  await page.waitForSelector("#sign-in", { state: "visible", timeout: WAIT.timeout });
  assert.match(await page.textContent("#error") ?? "", /This server needs a token: enter yours/);
  assert.match(await page.textContent("#sign-in") ?? "", /sign in with the token/);
  assert.deepEqual(await messagesShown(page), [await page.textContent("#error")]);
  await page.screenshot({ path: join(ARTIFACTS, "5-token-needed.png") });
  await page.fill("#token", "alice-token");
  await Promise.all([page.waitForEvent("load", { timeout: WAIT.timeout }), page.press("#token", "Enter")]);
  await page.waitForFunction(() => (window as any).cinevol?.status().framesPainted >= 1, null, WAIT);
  assert.ok(!(await page.isVisible("#sign-in")), "signed in");
  assert.equal((await status(page)).error, "");
  await page.close();
});

test("a server without tokens: the page opens at once; a sphere in 0.8 x 0.8 x 2 mm voxels is round on all three " +
     "slices (F3), its crosshair, edge letters and a measurement in millimetres", async () => {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  await page.goto(`http://127.0.0.1:${openGateway.port}/?volume=sphere`);
  const opened = await until(page, (s) => s.framesPainted >= 1, "a frame without a token");
  assert.equal(opened.error, "");
  assert.ok(!(await page.isVisible("#sign-in")), "no token asked for");
  assert.equal(await page.inputValue("#volumes"), "sphere");
  assert.ok((await messagesShown(page)).length <= 1, JSON.stringify(await messagesShown(page)));

  await page.keyboard.press("F3");
  assert.ok(await page.$eval("#stage", (e) => e.classList.contains("grid")), "F3: the 2x2 layout");
  await page.selectOption("#window-preset", "soft-tissue");  // 350 wide about 50: mid-grey on the sphere's surface
  await page.waitForFunction(() => [...document.querySelectorAll<HTMLImageElement>(".slice img")].every((img) =>
    img.complete && img.naturalWidth > 0 && img.parentElement!.querySelector(".slice-window")!.textContent === "W 350 L 50"),
                             null, WAIT);
  const axes = ["axial", "coronal", "sagittal"] as const;
  const shot = async (axis: string) => decodePng(await page.locator(`#slice-${axis} img`).screenshot());
  // The image alone, then with the crosshair over it (the page's CSP allows no style sheet from here: each element's own).
  const overlays = (visibility: string) => page.$$eval(".slice canvas, .slice span", (parts, v) => {
    for (const part of parts) (part as HTMLElement).style.visibility = v;
  }, visibility);
  await overlays("hidden");
  const discs = Object.fromEntries(await Promise.all(axes.map(async (a) => [a, discOn(await shot(a))] as const)));
  await overlays("");
  await page.screenshot({ path: join(ARTIFACTS, "13-sphere-2x2.png") });
  for (const axis of axes) {
    const { width, height, x, y } = discs[axis];
    assert.ok(width > 150, `${axis}: the sphere drawn ${width.toFixed(1)} pixels wide`);
    assert.ok(Math.abs(width / height - 1) < 0.03, `${axis}: the sphere drawn ${width.toFixed(1)} x ${height.toFixed(1)} pixels`);
    const cross = crosshairOn(await shot(axis));  // through the volume's centre, the sphere's
    assert.ok(Math.hypot(cross.x - x, cross.y - y) < 2.5,
              `${axis}: the crosshair at ${JSON.stringify(cross)}, the sphere's centre at ${x.toFixed(1)}, ${y.toFixed(1)}`);
  }
  const letters = await page.$eval("#slice-coronal", (pane) => {
    const img = pane.querySelector("img")!.getBoundingClientRect();
    const gap = (edge: string) => {
      const r = pane.querySelector(`.edge-${edge}`)!.getBoundingClientRect();
      return { left: r.left - img.left, right: img.right - r.right, top: r.top - img.top, bottom: img.bottom - r.bottom }[edge]!;
    };
    return { left: gap("left"), right: gap("right"), top: gap("top"), bottom: gap("bottom") };
  });
  for (const [edge, gap] of Object.entries(letters)) {
    assert.ok(gap >= -1 && gap < 8, `coronal: the ${edge} letter ${gap.toFixed(1)} pixels inside the image's ${edge} edge`);
  }

  // Across the coronal slice, down its 2 mm rows and along its 0.8 mm columns: both read the diameter.
  const coronal = (await page.locator("#slice-coronal img").boundingBox())!, disc = discs.coronal;
  for (const [dx, dy] of [[0, disc.height / 2], [disc.width / 2, 0]]) {
    const before = (await page.$$("#measurements li")).length;
    await page.click("#measure-distance");
    await page.mouse.click(coronal.x + disc.x - dx, coronal.y + disc.y - dy);
    await page.mouse.click(coronal.x + disc.x + dx, coronal.y + disc.y + dy);
    await page.waitForFunction((n) => document.querySelectorAll("#measurements li").length > n, before, WAIT);
    const text = await page.textContent(`#measurements li:nth-child(${before + 1})`) ?? "";
    const mm = Number(/Distance (\d+\.\d) mm/.exec(text)?.[1]);
    assert.ok(Math.abs(mm - 2 * SPHERE.radiusMm) < 0.8, `a ${dx ? "horizontal" : "vertical"} measurement reads "${text}"`);
  }
  await page.screenshot({ path: join(ARTIFACTS, "14-sphere-measured.png") });
  await page.keyboard.press("F3");
  assert.ok(await page.$eval("#stage", (e) => !e.classList.contains("grid")), "F3 again: the 3D view alone");
  assert.ok(!(await page.isVisible("#slice-coronal")));
  await page.close();
});

test("after a transfer-function edit the next drag turns the picture from where it is: no jump (issue 56)", async () => {
  // The old fault: a session on a named view was framed again by the server after a transfer-function edit (what
  // the function shows), while the page kept the eye CreateSession had answered and dragged from there, so the first
  // drag after a preset threw the picture to another distance. The state's camera is numbers now, and the page drags
  // from it. On the sphere, ct-lung shows the whole box where ct-bone (its default) shows the sphere: framed again,
  // the picture was 30 to 37 grey levels from what a drag of 3 pixels (1.2 degrees) shows.
  const page = await browser.newPage({ viewport: { width: 900, height: 600 } });
  await page.goto(`http://127.0.0.1:${openGateway.port}/?volume=sphere`);
  await until(page, (s) => s.framesPainted >= 2, "the sphere's first frames");
  const other = (await status(page)).preset === "ct-lung" ? "ct-bone" : "ct-lung";
  await page.selectOption("#preset", other);
  await page.waitForFunction((p) => (window as any).cinevol.status().preset === p, other, WAIT);
  await settled(page);
  await framesAfter(page, 6);
  const edited = [await sample(page), await framesAfter(page, 2).then(() => sample(page))];
  const noise = meanDifference(edited[0].grid, edited[1].grid), camera = (await status(page)).camera!;
  await drag(page, 3, 0);
  await settled(page);
  await framesAfter(page, 6);  // refined again: only the turn is left to tell
  const dragged = await sample(page);
  await page.screenshot({ path: join(ARTIFACTS, "15-drag-after-preset.png") });
  const change = meanDifference(edited[1].grid, dragged.grid);
  assert.ok(change <= 3 * noise + 6, `the first drag after ${other} changed the picture by ${change.toFixed(2)} ` +
            `(frame to frame: ${noise.toFixed(2)}): it jumped`);
  // The camera dragged from is the state's: the drag turned it about the same target at the same distance.
  const after = (await status(page)).camera!;
  const distance = (c: typeof camera) => Math.hypot(c.eye.x - c.target.x, c.eye.y - c.target.y, c.eye.z - c.target.z);
  assert.ok(Math.abs(distance(after) / distance(camera) - 1) < 1e-4, `${JSON.stringify(camera)} -> ${JSON.stringify(after)}`);
  assert.deepEqual(after.target, camera.target);
  await page.close();
});

test("the gateway killed and restarted mid-session: the page resumes the same session", async () => {
  const before = await status(alice);
  const port = gateway.port;
  await stop(gateway, "SIGKILL");
  await alice.waitForFunction(() => /Connection lost/.test((window as any).cinevol.status().banner), null, WAIT);
  await alice.screenshot({ path: join(ARTIFACTS, "6-gateway-lost.png") });
  gateway = await startGateway(port);
  await alice.waitForFunction((n) => {
    const s = (window as any).cinevol.status();
    return !/Connection lost/.test(s.banner) && s.framesPainted > n;
  }, before.framesPainted, WAIT);
  assert.ok((await status(alice)).messages.some((m) => /Reconnected: the same session/.test(m)));
  await framesAfter(alice, 2);
  assert.equal((await status(alice)).sessionId, before.sessionId);
  await alice.screenshot({ path: join(ARTIFACTS, "7-resumed.png") });
});

test("two principals cannot see each other's sessions", async () => {
  const aliceSession = (await status(alice)).sessionId;
  const bob = await browser.newPage({ viewport: { width: 800, height: 500 } });
  await bob.goto(`${base()}/?session=${encodeURIComponent(aliceSession)}#token=bob-token`);
  await bob.waitForFunction(() => document.getElementById("error")!.textContent!.length > 0, null, WAIT);
  assert.match(await bob.textContent("#error") ?? "", /another user|not found/i);
  await bob.screenshot({ path: join(ARTIFACTS, "8-other-principal.png") });
  await bob.close();
  // The Connect protocol through the gateway, as a script would call it: bob's status lists none of alice's sessions.
  const answer = await fetch(`${base()}/cinevol.v1.ServerService/GetStatus`, {
    method: "POST", body: "{}", headers: { "content-type": "application/json", authorization: "Bearer bob-token" },
  });
  assert.equal(answer.status, 200);
  const bobStatus = await answer.json() as { sessions?: { sessionId: string }[] };
  assert.ok(!(bobStatus.sessions ?? []).some((s) => s.sessionId === aliceSession));
});

test("sharing: a link's viewer watches alice's session, points, cannot drive until made presenter, and is cut off when revoked",
     async () => {
  const owner = await browser.newPage({ viewport: { width: 900, height: 540 } });
  await owner.goto(`${base()}/?volume=phantom:head#token=alice-token`);
  await until(owner, (s) => s.framesPainted >= 2, "alice's session");
  // The Share panel: a link, as a viewer, for 15 minutes, pointer allowed.
  await owner.click("#share summary");
  await owner.selectOption("#share-role", "1");
  await owner.selectOption("#share-expires", "900");
  await owner.check("#share-pointer");
  await owner.click("#share-create");
  await owner.waitForFunction(() => (document.getElementById("share-link") as HTMLInputElement).value !== "", null, WAIT);
  const link = await owner.inputValue("#share-link");
  assert.match(link, new RegExp(`^${base()}/#grant=cvg_[^&]+$`), "the secret rides in the fragment");
  const grant = decodeURIComponent(link.split("#grant=")[1]);
  await waitForText(owner, "#share-grants", /link g\w+ · viewer · pointer · expires in 1[45] min · 0 watching/);

  // The viewer: no token, a window of another size; the session's frames as alice's page paints them.
  const viewer = await browser.newPage({ viewport: { width: 800, height: 500 } });
  await viewer.goto(link, { waitUntil: "domcontentloaded" });
  await waitForText(viewer, "#presence", /^Watching alice · 1 viewer$/);
  assert.ok(!viewer.url().includes("grant"), "the secret leaves the address bar");
  await waitForText(owner, "#presence", /^Shared · 1 viewer$/);
  await waitForText(owner, "#share-grants", /1 watching/);
  await drag(owner, 60, 0);  // alice turns it a little: frames for both, whatever refinement had reached
  let common: number[] = [];
  for (const end = Date.now() + WAIT.timeout; common.length < 2 && Date.now() < end; await sleep(200)) {
    const [a, v] = [await status(owner), await status(viewer)];
    common = a.frameIds.filter((id) => v.frameIds.includes(id));
  }
  assert.ok(common.length >= 2, `the viewer paints frames alice's page paints: ${JSON.stringify(common)}`);
  const aliceFrame = (await status(owner)).lastFrame!, viewerFrame = (await status(viewer)).lastFrame!;
  assert.deepEqual([viewerFrame.width, viewerFrame.height], [aliceFrame.width, aliceFrame.height],
                   "the session's frames, not the viewer's window");
  await viewer.screenshot({ path: join(ARTIFACTS, "10-viewer.png") });

  // The viewer's controls are off, its drag sends nothing, and the server refuses a viewer's camera anyway.
  assert.equal(await viewer.isDisabled("#preset"), true);
  assert.equal(await viewer.isHidden("#share"), true);
  await settled(owner);  // alice's own turn shown: from here only refinement changes her picture
  const still = [await sample(owner), await sleep(1500).then(() => sample(owner))];
  const noise = meanDifference(still[0].grid, still[1].grid);
  await drag(viewer, 200, 40);
  await sleep(1500);
  const after = await sample(owner), aliceNow = await status(owner);
  assert.ok(meanDifference(still[1].grid, after.grid) <= 3 * noise + 2,
            `alice's picture moved by the viewer's drag: ${meanDifference(still[1].grid, after.grid).toFixed(2)} ` +
            `(refinement alone: ${noise.toFixed(2)})`);
  assert.ok(aliceNow.lastFrame!.lastEventSeq <= aliceNow.eventsSent, "no event but alice's own in her frames");
  assert.equal((await status(viewer)).eventsByKind.camera ?? 0, 0, "no camera sent by a viewer");
  const refused = await fetch(`${base()}/cinevol.v1.SessionService/SendEvents`, {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ grant, events: [{ seq: "1", camera: { view: "LEFT" } }] }),
  });
  assert.equal(refused.status, 403, await refused.text());

  // Pointers: the viewer's on alice's page where it points on its own; alice's on the viewer's, and neither on its own.
  const vbox = (await viewer.locator("#view").boundingBox())!;
  const fit = Math.min(vbox.width / aliceFrame.width, vbox.height / aliceFrame.height);  // the frame shown whole, centred
  const onFrame = (fx: number, fy: number) => [vbox.x + (vbox.width - aliceFrame.width * fit) / 2 + fx * aliceFrame.width * fit,
                                               vbox.y + (vbox.height - aliceFrame.height * fit) / 2 + fy * aliceFrame.height * fit];
  await viewer.mouse.move(...(onFrame(0.5, 0.5) as [number, number]));
  await viewer.mouse.move(...(onFrame(0.25, 0.75) as [number, number]), { steps: 5 });
  const pointed = await until(owner, (s) => s.pointers.some((p) => p.who.startsWith("link ") && Math.abs(p.x - 0.25) < 0.02 &&
                                                     Math.abs(p.y - 0.75) < 0.02), "the viewer's pointer on alice's page");
  assert.equal(pointed.pointers.length, 1, JSON.stringify(pointed.pointers));
  await owner.screenshot({ path: join(ARTIFACTS, "11-viewer-pointer-on-alice.png") });
  const obox = (await owner.locator("#view").boundingBox())!;
  await owner.mouse.move(obox.x + obox.width * 0.6, obox.y + obox.height * 0.4, { steps: 5 });
  const seen = await until(viewer, (s) => s.pointers.some((p) => p.who === "alice"), "alice's pointer on the viewer's page");
  assert.ok(!seen.pointers.some((p) => p.who.startsWith("link ")), "the viewer's own pointer is not drawn for it");
  assert.ok(!(await status(owner)).pointers.some((p) => p.who === "alice"), "nor alice's for her");
  await viewer.mouse.move(vbox.x - 50, vbox.y + 10);  // onto the panel: it leaves the view, and alice's
  await until(owner, (s) => !s.pointers.some((p) => p.who.startsWith("link ")), "the viewer's pointer hidden on leaving");

  // Made presenter, the viewer drives alice's picture; taken back, it watches again.
  await owner.click("#share-grants button:text('Make presenter')");
  await until(viewer, (s) => s.driving && /^link /.test(s.presenter), "the viewer presenting");
  await waitForText(viewer, "#presence", /^You present/);
  await waitForText(owner, "#presence", /^link g\w+ presents · 1 viewer$/);
  assert.equal((await status(owner)).driving, true, "the owner may always drive");
  const before = await sample(owner);
  await drag(viewer, 200, 40);
  await until(viewer, (s) => (s.eventsByKind.camera ?? 0) > 0, "the presenter's camera sent");
  await framesAfter(owner, 4);
  const turned = await sample(owner);
  assert.ok(meanDifference(before.grid, turned.grid) > 3 * noise + 2,
            `the presenter's drag left alice's picture as it was: ${meanDifference(before.grid, turned.grid).toFixed(2)}`);
  await owner.click("#share-take-back");
  await until(viewer, (s) => !s.driving && s.presenter === "alice", "the role taken back");
  await waitForText(viewer, "#presence", /^Watching alice/);

  // Revoked: the viewer's stream ends at once, in plain words.
  await owner.click("#share-grants button:text('Revoke')");
  await waitForText(viewer, "#error", /share has ended: its owner revoked it/);
  await viewer.screenshot({ path: join(ARTIFACTS, "12-viewer-revoked.png") });
  await until(owner, (s) => s.viewers === 0, "no viewer left");
  await owner.waitForFunction(() => document.querySelectorAll("#share-grants li").length === 0, null, WAIT);
  await viewer.close();

  // A user's share: their token too; without it the page asks for one.
  await owner.fill("#share-principal", "bob");
  await owner.click("#share-create");
  await owner.waitForFunction((l) => (document.getElementById("share-link") as HTMLInputElement).value !== l, link, WAIT);
  const bobLink = await owner.inputValue("#share-link");
  const bob = await browser.newPage({ viewport: { width: 640, height: 480 } });
  await bob.goto(`${bobLink}&token=bob-token`, { waitUntil: "domcontentloaded" });
  await waitForText(bob, "#presence", /^Watching alice · 1 viewer$/);
  await bob.close();
  const anonymous = await browser.newPage({ viewport: { width: 640, height: 480 } });
  await anonymous.goto(bobLink, { waitUntil: "domcontentloaded" });
  await waitForText(anonymous, "#error", /your own token/);
  assert.ok(await anonymous.isVisible("#sign-in"), "the sign-in form is offered");
  await anonymous.close();
  await owner.close();
});

test("a plain chromium --screenshot of the page's URL shows a rendered volume", () => {
  const file = join(ARTIFACTS, "9-plain-chromium.png");
  execFileSync(CHROMIUM, [...CHROMIUM_ARGS, "--headless", `--user-data-dir=${join(scratch, "profile")}`,
    `--screenshot=${file}`, "--window-size=900,600",
    `${base()}/?volume=phantom:head#token=alice-token`], { timeout: 120_000, stdio: "ignore" });
  const png = decodePng(readFileSync(file));
  // The view's half of the window (right of the 320-pixel panel): a volume is far from one flat colour.
  let sum = 0, sumSquares = 0, n = 0;
  for (let y = 0; y < png.height; y += 2) {
    for (let x = 340; x < png.width; x += 2) {
      const i = (y * png.width + x) * png.channels;
      const l = 0.2126 * png.pixels[i] + 0.7152 * png.pixels[i + 1] + 0.0722 * png.pixels[i + 2];
      sum += l;
      sumSquares += l * l;
      n += 1;
    }
  }
  const spread = Math.sqrt(sumSquares / n - (sum / n) ** 2);
  assert.ok(spread > 10, `the view is flat (luminance spread ${spread.toFixed(1)})`);
});

test("HTTPS towards the browser and TLS towards the server", async () => {
  const cert = join(scratch, "cert.pem"), key = join(scratch, "key.pem");
  execFileSync("openssl", ["req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
    "-days", "2", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
    "-keyout", key, "-out", cert], { stdio: "ignore" });
  let tlsServer: Running | undefined, tlsGateway: Running | undefined;
  try {
    tlsServer = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu", "--tls-cert", cert,
                                                 "--tls-key", key], "tls-server");
    tlsGateway = await startWithPortFile(WEB, ["--listen", "127.0.0.1:0", "--tls-cert", cert, "--tls-key", key,
      "--server", `127.0.0.1:${tlsServer.port}`, "--server-tls-ca", cert], "tls-gateway");
    const answer = await new Promise<{ status: number; body: string }>((resolve, reject) => {
      const call = request({ host: "127.0.0.1", port: tlsGateway!.port, method: "POST", ca: readFileSync(cert),
                             path: "/cinevol.v1.ServerService/GetStatus", headers: { "content-type": "application/json" },
                             timeout: 30_000 }, (res) => {
        let body = "";
        res.on("data", (d) => { body += d; });
        res.on("end", () => resolve({ status: res.statusCode ?? 0, body }));
      });
      call.on("error", reject);
      call.end("{}");
    });
    assert.equal(answer.status, 200, answer.body);
    assert.ok((JSON.parse(answer.body).presets as string[]).includes("ct-bone"));
    await assert.rejects(fetch(`http://127.0.0.1:${tlsGateway.port}/healthz`), "no plain HTTP beside TLS");
  } finally {
    await stop(tlsGateway);
    await stop(tlsServer);
  }
});

// The page in Debian's headless chromium against a real cinevol-server (CPU)
// and cinevol-web on free loopback ports (page_harness.ts), in this order:
// a session, the reading tools (page_reading.ts), signing in, the first-day
// checks on a sphere, a lost gateway, another principal, sharing
// (page_sharing.ts), a plain screenshot and TLS. Screenshots go to
// $CINEVOL_ARTIFACTS. Run directly (node page.test.mjs): exit 77 (skipped)
// without chromium.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { readFileSync } from "node:fs";
import { request } from "node:https";
import { join } from "node:path";
import { after, before, test } from "node:test";
import {
  ARTIFACTS, base, CHROMIUM, CHROMIUM_ARGS, framesAfter, meanDifference, messagesShown, run, sample, SERVER, settled,
  resizeWindow, setUp, startGateway, status, tearDown, until, WAIT, WEB,
} from "./page_harness.js";
import { readingTests, sphereTests } from "./page_reading.js";
import { sharingTests } from "./page_sharing.js";
import { decodePng } from "./png.js";
import { scratch, startWithPortFile, stop, type Running } from "./processes.js";

before(setUp);
after(tearDown);

test("the page opens from its URL, signs in from the fragment and streams at the canvas's size", async () => {
  const { alice } = run;
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
  const { alice } = run;
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
  const { alice } = run;
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
  const { alice } = run;
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

test("a time series: the Time controls show its phases, a phase changes the picture, Play steps through them",
     async () => {
  // A small canvas (400x240): the CPU's frames come quickly, and the loop's movie renders at the session's size.
  const page = await run.browser.newPage({ viewport: { width: 720, height: 240 } });
  await page.goto(`http://127.0.0.1:${run.openGateway.port}/?volume=beat`);
  await until(page, (s) => s.framesPainted >= 1, "a frame of the series");
  assert.ok(await page.isVisible("#time"), "the Time controls show for a volume of several phases");
  assert.equal(await page.textContent("#phase-label"), "Phase 1 of 4 (0 ms)");
  await framesAfter(page, 3);
  const before = await sample(page);
  await page.$eval("#phase", (e) => {
    (e as HTMLInputElement).value = "3";
    e.dispatchEvent(new Event("input"));
  });
  await settled(page);
  const after = await sample(page);
  assert.ok(meanDifference(before.grid, after.grid) > 2, "phase 4 moved the ball in the picture");
  assert.equal(await page.textContent("#phase-label"), "Phase 4 of 4 (150 ms)");
  await page.screenshot({ path: join(ARTIFACTS, "3-time-series.png") });

  // One phase a second, on the small canvas: slower than a CPU frame under
  // load, so no phase falls between two frames. At 8 a second, frames a
  // quarter second apart on a busy 2-core machine showed phases 1, 2 and 4
  // only; at 1 a second on a 640x540 canvas, while alice's session refined on
  // the other server, frames up to two seconds apart showed phases 4, 1 and 3.
  await page.fill("#phase-rate", "1");
  await page.$eval("#phase-rate", (e) => e.dispatchEvent(new Event("change")));
  await page.click("#play");
  await page.waitForFunction(() => document.getElementById("play")!.textContent === "Pause", null, WAIT);
  const labels = new Set<string>();
  for (const end = Date.now() + 30_000; labels.size < 4 && Date.now() < end;) {
    labels.add((await page.textContent("#phase-label")) ?? "");
    await page.waitForTimeout(50);
  }
  assert.equal(labels.size, 4, `playing showed every phase: ${[...labels].join(", ")}`);
  await page.click("#play");
  await page.waitForFunction(() => document.getElementById("play")!.textContent === "Play", null, WAIT);

  // A movie of the loop: 25 frames of the phases at the Time rate (1 a second), made by the server, small.
  await page.locator("#output summary").click();
  await page.selectOption("#movie-path", "phases");
  await page.fill("#movie-seconds", "1");
  await page.selectOption("#movie-quality", "4");
  const [download] = await Promise.all([page.waitForEvent("download", { timeout: 120_000 }), page.click("#movie-record")]);
  const saved = join(scratch, "page-loop.mp4");
  await download.saveAs(saved);
  assert.match(execFileSync("ffprobe", ["-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                                        "stream=nb_read_frames", "-of", "default=nw=1", saved]).toString(),
               /nb_read_frames=25/);
  await page.close();
});

test("a second volume fused by the address: its controls show, a colour map round-trips, its glow changes the picture",
     async () => {
  const page = await run.browser.newPage({ viewport: { width: 960, height: 540 } });
  await page.goto(`http://127.0.0.1:${run.openGateway.port}/?volume=sphere&fuse=hot&align=patient`);
  await until(page, (s) => s.framesPainted >= 1, "a frame of the fused scene");
  assert.ok(await page.isVisible("#fusion"), "the second volume's controls show while the scene fuses one");
  assert.equal(await page.textContent("#fusion-name"), "hot");
  await page.selectOption("#fusion-map", "GRAY");
  await settled(page);
  assert.equal(await page.$eval("#fusion-map", (e) => (e as HTMLSelectElement).value), "GRAY");
  const glowing = await sample(page);
  await page.uncheck("#fusion-glow");
  await settled(page);
  assert.ok(meanDifference(glowing.grid, (await sample(page)).grid) > 1, "without its glow the picture changed");
  await page.screenshot({ path: join(ARTIFACTS, "3-fusion.png") });
  await page.close();
});

test("a movie recorded on the page is made by the server and saved as an MP4 of its frames", async () => {
  const { alice } = run;
  const windowSize = alice.viewportSize()!;
  await resizeWindow(alice, 720, 240);  // a small movie
  await alice.locator("#output summary").click();
  assert.ok(await alice.locator("#movie-phases").isHidden(), "no loop to record for a volume of one phase");
  await alice.selectOption("#movie-path", "orbit");
  await alice.fill("#movie-seconds", "1");
  await alice.selectOption("#movie-quality", "4");
  const [download] = await Promise.all([alice.waitForEvent("download", { timeout: 120_000 }),
                                        alice.click("#movie-record")]);
  assert.equal(download.suggestedFilename(), "cinevol-movie.mp4");
  const saved = join(scratch, "page-movie.mp4");
  await download.saveAs(saved);
  const probed = execFileSync("ffprobe", ["-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                                          "stream=codec_name,nb_read_frames", "-of", "default=nw=1", saved]).toString();
  assert.match(probed, /codec_name=h264/);
  assert.match(probed, /nb_read_frames=25/);
  const said = (await status(alice)).messages;
  assert.ok(said.some((m) => /Movie recorded: 25 frames/.test(m)), JSON.stringify(said));
  await alice.locator("#output summary").click();
  await resizeWindow(alice, windowSize.width, windowSize.height);
});

test("a window resize changes the frame's size", async () => {
  const { alice } = run;
  const before = (await status(alice)).lastFrame!;
  await alice.setViewportSize({ width: 720, height: 620 });
  await alice.waitForFunction((w) => (window as any).cinevol.status().lastFrame.width !== w, before.width, WAIT);
  const after = (await status(alice)).lastFrame!;
  assert.equal(after.width, 720 - 320, "the canvas is the window less the 320-pixel panel");
  assert.ok(after.height > before.height);
  await alice.screenshot({ path: join(ARTIFACTS, "4-resized.png") });
});

readingTests();

test("a wrong token is refused with a message on the page", async () => {
  const { browser } = run;
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
  const { browser } = run;
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

sphereTests();

test("the gateway killed and restarted mid-session: the page resumes the same session", async () => {
  const { alice } = run;
  const before = await status(alice);
  const port = run.gateway.port;
  await stop(run.gateway, "SIGKILL");
  await alice.waitForFunction(() => /Connection lost/.test((window as any).cinevol.status().banner), null, WAIT);
  await alice.screenshot({ path: join(ARTIFACTS, "6-gateway-lost.png") });
  run.gateway = await startGateway(port);
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
  const { alice, browser } = run;
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

sharingTests();

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

// The page's PACS panel in Debian's headless chromium against a real Orthanc
// (orthanc.ts) holding the shared CT, stamped, behind a real cinevol-server
// (CPU) and cinevol-web, all on loopback: a search by patient ID finds the
// study, its CT series opens as a session that streams; then a still stored by
// the CLI (snapshot --store-to) leaves a presentation state in the study,
// which the re-listed series show as "PR" and which opens in the still's
// scene. Run directly (node pacs.test.mjs): exit 77 (skipped) without chromium
// or the shared data, a failure without Orthanc (CI must run it).
import assert from "node:assert/strict";
import { execFile } from "node:child_process";
import { existsSync, mkdirSync, rmSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { promisify } from "node:util";
import { after, before, test } from "node:test";
import { chromium, type Browser, type Page } from "playwright-core";
import {
  ARTIFACTS, CHROMIUM, CHROMIUM_ARGS, SERVER, status, until, WAIT, WEB, type V,
} from "./page_harness.js";
import {
  credentialsLine, dicomWeb, stampCt, startOrthanc, stopOrthanc, upload, whatIsMissing, type Orthanc,
} from "./orthanc.js";
import { scratch, startWithPortFile, stop, type Running } from "./processes.js";

const SHARED_DATA = process.env.CINEVOL_SHARED_DATA ?? "";
if (!existsSync(SHARED_DATA)) {
  console.log(`skipped: real data not found at '${SHARED_DATA}' (../shared/data beside the checkout)`);
  process.exit(77);
}
const CT_DICOM = join(SHARED_DATA, "ct-body-totalsegmentator", "example_ct_dicom");
const CLI = process.env.CINEVOL_CLI ?? "", LOOPBACK_BIND = process.env.CINEVOL_LOOPBACK_BIND;
const CT = { studyUid: "2.25.3410501", seriesUid: "2.25.3410501.1", patientId: "CINEVOL-WEB-PR-1",
             patientName: "Cinevol^Web" };
// The still's scene (Viewer.APresentationStateOpensItsSeriesInItsScene's): a bone preset, seen from in front of
// the patient (-y), in patient coordinates, at the height of the CT's slab (z -766.5 to -804.5).
const STILL_SCENE = { frame: "PATIENT_LPS", transferFunction: { preset: "ct-bone" },
                      camera: { eye: { x: 40, y: -700, z: -785 }, target: { x: 0, y: -150, z: -785 }, fovYDeg: 25 } };

const run = {} as { orthanc: Orthanc; server: Running; gateway: Running; browser: Browser; page: Page };

before(async () => {
  const missing = whatIsMissing(LOOPBACK_BIND);
  if (missing) throw new Error(missing);
  if (!existsSync(CLI)) throw new Error(`CINEVOL_CLI must name the built cinevol (it is '${CLI}')`);
  mkdirSync(join(scratch, "orthanc"));
  run.orthanc = await startOrthanc(join(scratch, "orthanc"), LOOPBACK_BIND!);
  await upload(run.orthanc, stampCt(CT_DICOM, join(scratch, "stamped"), CT));
  const credentials = join(scratch, "pacs-credentials");
  writeFileSync(credentials, credentialsLine("orthanc", run.orthanc), { mode: 0o600 });
  run.server = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu",
    "--pacs", `orthanc=${dicomWeb(run.orthanc)}`, "--pacs-credentials", credentials, "--pacs-timeout-seconds", "10"],
    "server");
  run.gateway = await startWithPortFile(WEB, ["--listen", "127.0.0.1:0", "--server", `127.0.0.1:${run.server.port}`],
                                        "gateway");
  run.browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, timeout: 60_000 });
  run.page = await run.browser.newPage({ viewport: { width: 800, height: 450 } });
});

after(async () => {
  await run.browser?.close().catch(() => {});
  await stop(run.gateway);
  await stop(run.server);
  await stopOrthanc(run.orthanc);
  for (const folder of ["orthanc", "stamped"]) rmSync(join(scratch, folder), { recursive: true, force: true });
});

test("a study found by patient ID lists its CT series, which opens as a session that streams", async () => {
  const { page } = run;
  await page.goto(`http://127.0.0.1:${run.gateway.port}/`);
  // The page opens the server's first volume (a phantom) on its own: the series must open in a session of its own.
  const phantom = await until(page, (s) => s.sessionId !== "" && s.framesPainted > 0, "the first volume's frame");
  const phantomVolume = await page.inputValue("#volumes");
  await page.waitForSelector("#pacs", { state: "visible", timeout: WAIT.timeout });
  assert.equal(await page.inputValue("#pacs-name"), "orthanc");
  await listSeries(page);
  assert.match(await openListed(page, /^CT · /), /20 images/);
  const opened = await until(page, (s) => s.sessionId !== phantom.sessionId && s.framesPainted > phantom.framesPainted,
                             "a session of the CT, and a frame");
  await until(page, (s) => s.framesPainted > opened.framesPainted, "another frame of the CT's session");
  assert.equal(opened.error, "");
  const volume = await page.inputValue("#volumes");
  console.log(`# the series loaded as volume ${volume}`);
  assert.notEqual(volume, phantomVolume, "the volume list shows the loaded series open");
  await page.screenshot({ path: join(ARTIFACTS, "pacs-1-ct.png") });
});

test("a still stored with its presentation state opens from the re-listed series in the still's scene", async () => {
  const { page } = run;
  const first = await status(page);
  const stored = await storeStill(await page.inputValue("#volumes"));
  assert.match(stored, /its presentation state: series /);
  await listSeries(page);
  await openListed(page, /^PR · /);
  const presented = await until(page, (s) => s.sessionId !== first.sessionId && s.camera !== null,
                                "a session of the presentation state");
  await until(page, (s) => s.framesPainted > presented.framesPainted, "a frame of the presented session");
  // The state's camera lies in the volume-centred frame; the still's scene said where in the patient.
  const volume = await describe(await page.inputValue("#volumes"));
  const eye = toPatient(presented.camera!.eye, volume), target = toPatient(presented.camera!.target, volume);
  assert.ok(near(eye, STILL_SCENE.camera.eye), `the eye is at ${JSON.stringify(eye)} in the patient`);
  assert.ok(near(target, STILL_SCENE.camera.target), `the target is at ${JSON.stringify(target)} in the patient`);
  assert.equal(presented.preset, "ct-bone");
  assert.equal((await status(page)).error, "");
  // The same state as a DICOMweb target: its series rendered in its scene.
  const [, stateSeries, stateUid] = /its presentation state: series ([0-9.]+), instance ([0-9.]+)/.exec(stored)!;
  const state = `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc/studies/${CT.studyUid}/series/${stateSeries}` +
                `/instances/${stateUid}/rendered3D`;
  const picture = await fetch(`${state}?viewport=64,48&quality=20`, { headers: { accept: "image/png" } });
  assert.equal(picture.status, 200, await picture.clone().text());
  assert.deepEqual(pngSize(Buffer.from(await picture.arrayBuffer())), { width: 64, height: 48 });
  assert.equal((await fetch(`${state}?renderingmethod=volume_rendered`)).status, 400, "what the state says");
  await page.screenshot({ path: join(ARTIFACTS, "pacs-2-presentation.png") });
});

test("an IHE Invoke Image Display launch opens the study it names, and a malformed one is refused with 400", async () => {
  const { page } = run;
  const base = `http://127.0.0.1:${run.gateway.port}`;
  for (const launch of [`/IHEInvokeImageDisplay?requestType=STUDY&studyUID=${CT.studyUid}&viewerType=IHE_BIR`,
                        `/iid?requestType=PATIENT&patientID=${encodeURIComponent(`${CT.patientId}^^^&1.2.3&ISO`)}`]) {
    const before = await status(page).catch(() => undefined);
    await page.goto(base + launch);
    const opened = await until(page, (s) => s.sessionId !== "" && s.sessionId !== before?.sessionId &&
                               s.framesPainted > 0, `a session of the CT from ${launch}`);
    assert.equal(opened.error, "");
    const volume = await describe(await page.inputValue("#volumes"));
    assert.equal((volume as unknown as { source: string }).source,
                 `pacs:orthanc/${CT.studyUid}/${CT.seriesUid}`, `the CT opened from ${launch}`);
  }
  for (const [launch, reason] of [["/iid?requestType=SERIES&studyUID=1.2", "requestType: 'SERIES'"],
                                  ["/IHEInvokeImageDisplay?requestType=STUDY", "give studyUID or accessionNumber"]]) {
    const answer = await fetch(base + launch);
    assert.equal(answer.status, 400, launch);
    const said = await answer.text();
    assert.ok(said.includes(reason), `${launch}: ${said}`);
  }
  await page.screenshot({ path: join(ARTIFACTS, "pacs-3-iid.png") });
});

test("the DICOMweb origin renders the series by URL: 3D as JPEG and PNG, an MPR slab, the parameters used", async () => {
  const series = `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc/studies/${CT.studyUid}/series/${CT.seriesUid}`;
  const jpeg = await fetch(`${series}/rendered3D?orientation=a&viewport=128,96&quality=30`,
                           { headers: { accept: "image/jpeg" } });
  assert.equal(jpeg.status, 200, await jpeg.clone().text());
  assert.equal(jpeg.headers.get("content-type"), "image/jpeg");
  assert.deepEqual(jpegSize(Buffer.from(await jpeg.arrayBuffer())), { width: 128, height: 96 });
  const png = await fetch(`${series}/rendered3d?orientation=l&viewport=64,48&quality=20&accept=image/png`);
  assert.equal(png.status, 200);
  assert.deepEqual(pngSize(Buffer.from(await png.arrayBuffer())), { width: 64, height: 48 });
  const view = "viewpointposition=0,-700,-785&viewpointlookat=0,-150,-785&viewpointup=0,0,1";
  const meta = await fetch(`${series}/rendered3D?${view}&viewport=64,48&renderedvolumetricmetadata=yes`);
  assert.equal(meta.headers.get("content-type"), "application/dicom+json");
  const [used] = await meta.json() as Record<string, { Value: number[] }>[];
  assert.equal(used["0070120D"].Value[0], "VOLUME_RENDERED" as unknown as number);
  assert.equal(used["00280011"].Value[0], 64);
  const mpr = await fetch(`${series}/renderedmpr?renderingmethod=maximum_ip&mprslab=10&${view}&window=400,40,linear`,
                          { headers: { accept: "image/png" } });
  assert.equal(mpr.status, 200, await mpr.clone().text());
  assert.ok(pngSize(Buffer.from(await mpr.arrayBuffer())).width > 100, "a slab across the CT");
  for (const [url, status, said] of [
    [`${series}/rendered3D?renderingmethod=maximum_ip`, 400, "renderingmethod"],
    [`${series}/rendered3D?viewport=0,10`, 400, "viewport"],
    [`${series}/renderedmpr?renderingmethod=average_ip`, 400, "viewpointposition"],
    [`${series}/rendered3D?accept=video/mp4`, 406, "video"],
    [`http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc/studies/${CT.studyUid}/series/2.25.999/rendered3D`, 404, ""],
    [`http://127.0.0.1:${run.gateway.port}/dicom-web/nope/studies/1.2/series/1.2/rendered3D`, 400, "nope"],
  ] as [string, number, string][]) {
    const answer = await fetch(url);
    const text = await answer.text();
    assert.equal(answer.status, status, `${url}: ${text}`);
    assert.ok(text.includes(said), `${url}: ${text}`);
  }
});

/** A baseline or progressive JPEG's size, from its first start-of-frame marker. */
function jpegSize(jpeg: Buffer): { width: number; height: number } {
  for (let at = 2; at + 9 < jpeg.length;) {
    const marker = jpeg[at + 1], length = jpeg.readUInt16BE(at + 2);
    if (marker >= 0xc0 && marker <= 0xc2) return { height: jpeg.readUInt16BE(at + 5), width: jpeg.readUInt16BE(at + 7) };
    at += 2 + length;
  }
  throw new Error("no JPEG frame header");
}

const pngSize = (png: Buffer) => ({ width: png.readUInt32BE(16), height: png.readUInt32BE(20) });

/** Searches by the CT's patient ID and opens the one study found: its series are listed. */
async function listSeries(page: Page): Promise<void> {
  await page.fill("#pacs-query", CT.patientId);
  await page.click("#pacs-search");
  await openListed(page, /20221208/);  // the study (its date); a series' line has none
}

/** Clicks the PACS list's line that matches; on timeout says what the list showed. Its text. */
async function openListed(page: Page, pattern: RegExp): Promise<string> {
  const line = page.locator("#pacs-results button", { hasText: pattern }).first();
  try {
    await line.waitFor({ timeout: WAIT.timeout });
  } catch (e) {
    throw new Error(`the PACS list never showed ${pattern}: it shows "${await page.textContent("#pacs-results")}", ` +
                    `the error line "${await page.textContent("#error")}" (${e})`);
  }
  const text = (await line.textContent()) ?? "";
  await line.click();
  return text;
}

/** The CLI's still of `volumeId` in STILL_SCENE, stored on the PACS with its presentation state; what it printed. */
async function storeStill(volumeId: string): Promise<string> {
  const scene = join(scratch, "still-scene.json");
  writeFileSync(scene, JSON.stringify(STILL_SCENE));
  const { stdout, stderr } = await promisify(execFile)(CLI, ["snapshot", "--server", `127.0.0.1:${run.server.port}`,
    "--volume", volumeId, "--scene", scene, "--width", "64", "--height", "48", "--spp", "2",
    "--out", join(ARTIFACTS, "pacs-still.png"), "--store-to", "orthanc"], { timeout: 60_000 });
  return stdout + stderr;
}

/** What the server says of a volume (proto3 JSON of VolumeInfo): where it lies in the patient. */
interface Placement {
  direction: number[];  // row-major: column c is index axis c's direction in the patient
  originMm: V;          // voxel (0, 0, 0)'s centre
  spacingMm: V;
  dims: V;
}

async function describe(volumeId: string): Promise<Placement> {
  const { stdout } = await promisify(execFile)(CLI, ["volumes", "describe", volumeId, "--json",
    "--server", `127.0.0.1:${run.server.port}`], { timeout: 30_000 });
  return JSON.parse(stdout) as Placement;
}

/** A point of the volume-centred frame in the patient (LPS mm): origin + D (v + (dims - 1) spacing / 2). */
function toPatient(v: V, p: Placement): V {
  const axes = ["x", "y", "z"] as const;
  const index = axes.map((k) => v[k] + ((p.dims[k] - 1) * p.spacingMm[k]) / 2);
  const [x, y, z] = axes.map((k, r) => p.originMm[k] + index.reduce((sum, u, c) => sum + p.direction[3 * r + c] * u, 0));
  return { x, y, z };
}

const near = (a: V, b: V) => Math.abs(a.x - b.x) < 0.01 && Math.abs(a.y - b.y) < 0.01 && Math.abs(a.z - b.z) < 0.01;

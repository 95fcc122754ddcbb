// The page's PACS panel in Debian's headless chromium against a real Orthanc
// (orthanc.ts) holding the shared CT, stamped, behind a real cinevol-server
// (CPU) and cinevol-web, all on loopback: a search by patient ID finds the
// study, its CT series opens as a session that streams; then a still stored by
// the CLI (snapshot --store-to) leaves a presentation state in the study,
// which the re-listed series show as "PR" and which opens in the still's
// scene; the page's own measurement stored as an SR that a new session of the
// CT reads back; a DICOM SEG of the CT (seg_fixture.ts) opened as its labels.
// The DICOMweb origin (gateway/rendered.ts): each kind by URL, bad parameters
// refused with nothing touched, a third-party client (dicomweb-client) reading
// the series from Orthanc and its renderings from cinevol-web, an MPR that is
// `cinevol slice` of the same plane, and signed URLs for <img> against a
// second server that needs tokens. What cinevol stored is read back from
// Orthanc by WADO-RS with a second, independent DICOM reader (dcmjs) and its
// values compared with what cinevol says it wrote: the Secondary Capture's
// pixels are the still's, the presentation state's camera the scene it gives
// back, the SR's coordinates and length the page's measurement.
// Run directly (node pacs.test.mjs): exit 77 (skipped) without chromium or
// the shared data, a failure without Orthanc (CI must run it).
import assert from "node:assert/strict";
import { execFile, execFileSync } from "node:child_process";
import { existsSync, mkdirSync, readdirSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { promisify } from "node:util";
import { after, before, test } from "node:test";
import dcmjs, { type Naturalized } from "dcmjs";
import { api as dicomweb } from "dicomweb-client";
import { chromium, type Browser, type Page } from "playwright-core";
import {
  ARTIFACTS, CHROMIUM, CHROMIUM_ARGS, drag, SERVER, status, until, WAIT, waitForText, WEB, type PageStatus, type V,
} from "./page_harness.js";
import {
  authorization, credentialsLine, dicomWeb, stampCt, startOrthanc, stopOrthanc, upload, whatIsMissing, type Orthanc,
} from "./orthanc.js";
import { decodePng } from "./png.js";
import type { Pixels } from "../gateway/png.js";
import { scratch, startWithPortFile, stop, tokensFile, type Running } from "./processes.js";
import { FetchXhr } from "./xhr.js";
import { ctSlice, dicomLab, segmentationFile, type SegFrame, type Vec3 } from "./seg_fixture.js";

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

const run = {} as { orthanc: Orthanc; server: Running; gateway: Running; browser: Browser; page: Page;
                    tokenServer?: Running; tokenGateway?: Running };

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
  await stop(run.tokenGateway);
  await stop(run.tokenServer);
  await stopOrthanc(run.orthanc);
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
  const opened = await until(page, (s) => s.sessionId !== first.sessionId, "a session of the presentation state");
  // The camera shown is the last session's until the new one's first state, which comes before its frames: two
  // frames painted since the new session began (one may be the last of the old), so the state came.
  const presented = await until(page, (s) => s.framesPainted > opened.framesPainted + 1 && s.camera !== null,
                                "a frame of the presented session");
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
  // Both objects as a second reader (dcmjs) reads them from the PACS: the capture is the still the CLI wrote, the
  // state presents the CT in the camera of the scene that `cinevol pacs load --presentation` gives back.
  const [, stillStudy, stillSeries, stillUid] =
    /stored in PACS 'orthanc': study ([0-9.]+), series ([0-9.]+), instance ([0-9.]+)/.exec(stored)!;
  assert.equal(stillStudy, CT.studyUid, "the still went into the CT's study");
  const ct = await ctAsStored();
  const still = decodePng(readFileSync(join(ARTIFACTS, "pacs-still.png")));
  assertCaptureIsTheStill(await readBack(stillSeries, stillUid), still);
  assertStatePresentsTheStill(await readBack(stateSeries, stateUid), ct, { series: stillSeries, instance: stillUid },
                              await presentedCamera(stateSeries, stateUid));
  console.log(`# dcmjs read back capture ${stillUid} (${still.width}x${still.height}, the still's pixels) and ` +
              `presentation state ${stateUid} (the scene's camera, the CT's ${ct.instances.length} images)`);
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
  // A swivel: a quarter turn, 30 degrees a frame at 10 frames a second, is an MP4 of 3 frames (ffprobe decodes them).
  const swivel = await fetch(`${series}/rendered3D?orientation=a&viewport=64,48&quality=10&swivelrange=90` +
                             "&animationstepsize=30&animationrate=10", { headers: { accept: "video/mp4" } });
  assert.equal(swivel.status, 200, await swivel.clone().text());
  assert.equal(swivel.headers.get("content-type"), "video/mp4");
  const video = join(scratch, "swivel.mp4");
  writeFileSync(video, Buffer.from(await swivel.arrayBuffer()));
  const probed = execFileSync("ffprobe", ["-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                                          "stream=codec_name,width,height,nb_read_frames", "-of", "default=nw=1",
                                          video]).toString();
  for (const expected of ["codec_name=h264", "width=64", "height=48", "nb_read_frames=3"]) {
    assert.ok(probed.includes(expected), `${expected} in ${probed}`);
  }
  // The issue's bad parameters: each refused with the standard's status and a message, and nothing else touched
  // (no session made or left, no volume loaded).
  const origin = `http://127.0.0.1:${run.gateway.port}/dicom-web`;
  const held = await serverHolds();
  await expectRefusals(held, [
    [`${series}/rendered3D?renderingmethod=maximum_ip`, 400, "renderingmethod"],
    [`${series}/rendered3D?renderingmethod=raytraced`, 400, "renderingmethod: 'raytraced' is not"],
    [`${series}/rendered3D?viewport=0,10`, 400, "viewport"],
    [`${series}/rendered3D?viewport=1000000,1000000`, 400, "viewport: each side a whole number in [1, 4096]"],
    [`${series}/rendered3D?viewpointposition=NaN,0,0&viewpointlookat=0,0,0`, 400, "viewpointposition: 'NaN,0,0'"],
    [`${series}/renderedmpr?viewpointposition=0,0,NaN&viewpointlookat=0,0,0`, 400, "viewpointposition"],
    [`${series}/renderedmpr?${view}&mprslab=1e6`, 400, "mprslab: a thickness in mm, 0 to 1e4"],
    [`${series}/renderedmpr?renderingmethod=average_ip`, 400, "viewpointposition"],
    [`${series}/renderedmpr?${view}&accept=image/jpeg`, 406, "image/png"],
    [`${series}/rendered3D?accept=video/mp4`, 400, "swivelrange: a video of a rendered volume is a swivel"],
    [`${series}/rendered3D?swivelrange=360&animationstepsize=0.01`, 400, "at most 3600"],
    [`${series}/renderedmpr?${view}&swivelrange=90`, 400, "swivel"],
    [`${origin}/orthanc/studies/${CT.studyUid}/series/2.25.999/rendered3D`, 404, ""],
    [`${origin}/nope/studies/1.2/series/1.2/rendered3D`, 400, "nope"],
    [`${origin}/http://127.0.0.1:9/dicom-web/studies/1.2/series/1.2/rendered3D`, 400, "is not a PACS name"],
    [`${origin}/${encodeURIComponent("http://127.0.0.1:9/")}/studies/1.2/series/1.2/rendered3D`, 400, "never an address"],
    [`${origin}/orthanc/studies/${CT.studyUid}/series/${CT.seriesUid}/thumbnail`, 404, "not a rendered resource"],
  ]);
});

test("a third-party DICOMweb client reads the series from Orthanc and its renderings from cinevol-web", async () => {
  // dicomweb-client (npm) speaks XMLHttpRequest, which node has not: a small one over fetch (xhr.ts).
  (globalThis as { XMLHttpRequest?: unknown }).XMLHttpRequest = FetchXhr;
  const pacs = new dicomweb.DICOMwebClient({ url: dicomWeb(run.orthanc), headers: authorization(run.orthanc),
                                             verbose: false, singlepart: false });
  const instances = await pacs.retrieveSeriesMetadata({ studyInstanceUID: CT.studyUid,
                                                        seriesInstanceUID: CT.seriesUid, request: {} });
  assert.equal(instances.length, 20, "the series' 20 images");
  const value = (i: number, tag: string) => (instances[i] as Record<string, { Value: number[] }>)[tag].Value;
  const zs = instances.map((_, i) => value(i, "00200032")[2]);
  const [x0, y0] = value(0, "00200032"), [rowMm, columnMm] = value(0, "00280030");
  const columns = value(0, "00280011")[0], rows = value(0, "00280010")[0];
  // The middle of the series, from what the PACS says of it: the look-at point of the views below.
  const middle = [x0 + ((columns - 1) * columnMm) / 2, y0 + ((rows - 1) * rowMm) / 2,
                  (Math.min(...zs) + Math.max(...zs)) / 2];
  console.log(`# the series from Orthanc: ${columns}x${rows} px, z ${Math.min(...zs)} to ${Math.max(...zs)} mm`);

  // Rendered resources have no method of their own in the client: its generic image and JSON requests.
  const origin = new dicomweb.DICOMwebClient({ url: `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc`,
                                               verbose: false, singlepart: false }) as unknown as GenericRequests;
  const series = `${origin.wadoURL}/studies/${CT.studyUid}/series/${CT.seriesUid}`;
  const [jpeg] = await origin._httpGetImage(`${series}/rendered3D`, [{ mediaType: "image/jpeg" }],
                                            { orientation: "a", viewport: "96,64", quality: 20 });
  const still = Buffer.from(jpeg);
  assert.deepEqual([still[0], still[1], still.at(-2), still.at(-1)], [0xff, 0xd8, 0xff, 0xd9], "JPEG's SOI and EOI");
  assert.deepEqual(jpegSize(still), { width: 96, height: 64 });
  const decoded = await decodedInBrowser(still, "image/jpeg");
  assert.deepEqual([decoded.width, decoded.height], [96, 64], "Chromium decodes the JPEG");
  assert.ok(decoded.mean > 1, `the anterior view shows the CT (mean ${decoded.mean})`);

  const view = { viewpointposition: `${middle[0]},${middle[1] - 600},${middle[2]}`,
                 viewpointlookat: middle.join(","), viewpointup: "0,0,1" };
  const mprQuery = { renderingmethod: "maximum_ip", mprslab: "10", ...view, window: "40,400,linear",
                     viewport: "160,120" };
  const [slab] = await origin._httpGetImage(`${series}/renderedmpr`, [{ mediaType: "image/png" }], mprQuery);
  const mpr = decodePng(Buffer.from(slab));
  assert.deepEqual([mpr.width, mpr.height], [160, 120], "the MPR at the viewport's size");
  assert.ok(mpr.pixels.some((v) => v > 50), "the slab shows the CT");
  const plain = await fetch(`${series}/renderedmpr?${new URLSearchParams(mprQuery)}`);
  assert.ok(Buffer.from(await plain.arrayBuffer()).equals(Buffer.from(slab)), "plain fetch, the same slab");

  const used = await origin._httpGetApplicationJson(`${series}/rendered3D`,
    { ...view, viewport: "96,64", renderedvolumetricmetadata: "yes" }) as Record<string, { Value: unknown[] }>[];
  assert.equal(used[0]["0070120D"].Value[0], "VOLUME_RENDERED");
  const target = used[0]["00701604"].Value as number[];
  assert.ok(target.every((v, k) => Math.abs(v - middle[k]) < 0.05), `the look-at point as asked, in the patient: ${target}`);
  assert.deepEqual([used[0]["00280011"].Value[0], used[0]["00280010"].Value[0]], [96, 64]);
});

test("an MPR at the size `cinevol slice` makes of the same plane is its slice; another size fits the section", async () => {
  const series = `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc/studies/${CT.studyUid}/series/${CT.seriesUid}`;
  // A coronal plane seen from in front (the view's right the patient's left), through the CT's slab; a soft-tissue
  // window (PS3.18: window=center,width; the CLI's --window is the width, --level the centre).
  const view = "viewpointposition=0,-700,-785&viewpointlookat=0,-150,-785&viewpointup=0,0,1";
  for (const slabMm of [10, 5000]) {
    const made = decodePng(await cliSlice(["--axis", "oblique", "--point", "0,-150,-785", "--normal", "0,1,0", "--row",
                                           "1,0,0", "--slab", String(slabMm), "--projection", "max"], String(slabMm)));
    const answer = await fetch(`${series}/renderedmpr?renderingmethod=maximum_ip&mprslab=${slabMm}&${view}` +
                               `&window=40,400,linear&viewport=${made.width},${made.height}`);
    assert.equal(answer.status, 200, await answer.clone().text());
    // A slab thicker than the volume is answered (the projection of all of it), and the answer says so.
    if (slabMm > 1000) assert.match(answer.headers.get("warning") ?? "", /^299 cinevol-web ".*projects all of it"$/);
    const answered = Buffer.from(await answer.arrayBuffer());
    writeFileSync(join(ARTIFACTS, `pacs-mpr-${slabMm}.png`), answered);
    const mpr = decodePng(answered);
    assert.deepEqual([mpr.width, mpr.height, mpr.channels], [made.width, made.height, made.channels]);
    // The same voxels (the PACS's files are the ones the CLI reads), the same plane and the same slice code
    // (server/reading/slice.cpp) at the same pixel size: at most a level of rounding apart.
    const { mean, most } = difference(mpr.pixels, made.pixels);
    console.log(`# slab ${slabMm} mm: ${made.width}x${made.height} px, mean difference ${mean}, most ${most}`);
    assert.ok(most <= 1, `slab ${slabMm} mm: the MPR and cinevol slice differ by up to ${most} levels`);
  }
  // A square viewport: the section, wider than tall, fitted across it, centred between black bands.
  const square = decodePng(Buffer.from(await (await fetch(
    `${series}/renderedmpr?renderingmethod=maximum_ip&mprslab=10&${view}&window=40,400,linear&viewport=200,200`))
    .arrayBuffer()));
  assert.deepEqual([square.width, square.height], [200, 200]);
  const rowLit = (y: number) => square.pixels.subarray(y * 600, (y + 1) * 600).some((v) => v > 0);
  const lit = [...Array(200).keys()].filter(rowLit);
  assert.ok(lit.length > 0 && lit.length < 100, `the section is a band (${lit.length} rows)`);
  assert.ok(Math.abs(lit[0] + lit.at(-1)! - 199) <= 2, `centred: rows ${lit[0]} to ${lit.at(-1)}`);
});

test("a rendered frame (Supplement 174) of an image lies on its own plane and grid: `cinevol slice` there", async () => {
  (globalThis as { XMLHttpRequest?: unknown }).XMLHttpRequest = FetchXhr;
  const pacs = new dicomweb.DICOMwebClient({ url: dicomWeb(run.orthanc), headers: authorization(run.orthanc),
                                             verbose: false, singlepart: false });
  const instances = await pacs.retrieveSeriesMetadata({ studyInstanceUID: CT.studyUid,
                                                        seriesInstanceUID: CT.seriesUid, request: {} });
  const image = instances[7] as Record<string, { Value: (string | number)[] }>;
  const sopInstanceUID = String(image["00080018"].Value[0]), z = Number(image["00200032"].Value[2]);
  const [columns, rows] = [Number(image["00280011"].Value[0]), Number(image["00280010"].Value[0])];

  const origin = new dicomweb.DICOMwebClient({ url: `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc`,
                                               verbose: false, singlepart: false });
  const [rendered] = await origin.retrieveInstanceFramesRendered({
    studyInstanceUID: CT.studyUid, seriesInstanceUID: CT.seriesUid, sopInstanceUID, frameNumbers: "1",
    mediaTypes: [{ mediaType: "image/png" }], queryParams: { window: "40,400,linear" } }) as ArrayBuffer[];
  const frame = decodePng(Buffer.from(rendered));
  assert.deepEqual([frame.width, frame.height], [columns, rows], "the image's own Columns x Rows");
  const made = decodePng(await cliSlice(["--axis", "axial", "--position", String(z)], `axial-${z}`));
  assert.deepEqual([made.width, made.height], [columns, rows]);
  const { mean, most } = difference(frame.pixels, made.pixels);
  console.log(`# frame 1 of image 8 (z ${z} mm): ${columns}x${rows} px, mean difference ${mean}, most ${most}`);
  assert.ok(most <= 1, `the frame and cinevol slice differ by up to ${most} levels`);
  assert.ok(frame.pixels.some((v) => v > 200), "the frame shows the CT");

  const instance = `http://127.0.0.1:${run.gateway.port}/dicom-web/orthanc/studies/${CT.studyUid}/series/` +
                   `${CT.seriesUid}/instances/${sopInstanceUID}`;
  const whole = await fetch(`${instance}/rendered?window=40,400,linear`);
  assert.equal(whole.status, 200, await whole.clone().text());
  assert.ok(Buffer.from(await whole.arrayBuffer()).equals(Buffer.from(rendered)), "a single-frame image is its frame");
  const fitted = decodePng(Buffer.from(await (await fetch(`${instance}/frames/1/rendered?viewport=200,100`))
    .arrayBuffer()));
  assert.deepEqual([fitted.width, fitted.height], [200, 100], "the viewport's size, the image fitted within it");
  const held = await serverHolds();
  await expectRefusals(held, [
    [`${instance}/frames/1,2/rendered`, 406, "multi-frame media type"],
    [`${instance}/frames/0/rendered`, 400, "frame numbers from 1"],
    [`${instance}/frames/2/rendered`, 404, "frame 2 is not one of them"],
    [`${instance}/frames/1/rendered?mprslab=10`, 400, "a rendered frame lies on its own plane"],
    [`${instance}/frames/1/rendered?accept=image/jpeg`, 406, "image/png"],
    [`${instance}/frames/1/rendered?viewport=1000000,10`, 400, "viewport"],
    [`${instance.replace(sopInstanceUID, "2.25.999")}/frames/1/rendered`, 404, "2.25.999"],
    [`${instance}/frames/x/rendered`, 400, "frames: a number"],
  ]);
});

test("a signed URL serves an <img> with no token, for its resource only, until it expires", async () => {
  // A server that needs tokens, on the same Orthanc, behind its own gateway.
  const tokens = tokensFile("alice-token alice\n");
  run.tokenServer = await startWithPortFile(SERVER, ["--listen", "127.0.0.1:0", "--backend", "cpu",
    "--auth-tokens", tokens, "--pacs", `orthanc=${dicomWeb(run.orthanc)}`,
    "--pacs-credentials", join(scratch, "pacs-credentials"), "--pacs-timeout-seconds", "10"], "token-server");
  run.tokenGateway = await startWithPortFile(WEB, ["--listen", "127.0.0.1:0", "--server",
                                                   `127.0.0.1:${run.tokenServer.port}`], "token-gateway");
  const base = `http://127.0.0.1:${run.tokenGateway.port}`;
  const path = `/dicom-web/orthanc/studies/${CT.studyUid}/series/${CT.seriesUid}/rendered3D`;
  const sign = (body: object, token = "alice-token") => fetch(`${base}/dicom-web/signed-url`, {
    method: "POST", headers: { authorization: `Bearer ${token}`, "content-type": "application/json" },
    body: JSON.stringify(body) });
  assert.equal((await fetch(`${base}${path}?viewport=64,48`)).status, 401, "the server needs a token");

  const made = await sign({ url: `${path}?orientation=a&viewport=64,48&quality=20&accept=image/png`, expiresIn: 120 });
  assert.equal(made.status, 200, await made.clone().text());
  const { url, expires } = await made.json() as { url: string; expires: string };
  assert.ok(!url.includes("alice-token") && /[?&]signature=[A-Za-z0-9_-]{43}$/.test(url), url);
  assert.ok(Math.abs(Date.parse(expires) - Date.now() - 120_000) < 10_000, expires);
  const picture = await fetch(base + url);  // no Authorization header
  assert.equal(picture.status, 200, await picture.clone().text());
  assert.deepEqual(decodePng(Buffer.from(await picture.arrayBuffer())).width, 64);
  // An <img> on a page of another origin, as a report would hold it: the other gateway's /healthz, a page with no
  // policy of ours, on loopback as the signed URL is.
  const page = await run.browser.newPage();
  try {
    await page.goto(`http://127.0.0.1:${run.gateway.port}/healthz`);
    await page.evaluate((src) => {
      const img = document.createElement("img");
      img.id = "still";
      img.src = src;
      document.body.append(img);
    }, `${base}${url.replace("viewport=64,48", "viewport=40,30")}`);
    await page.waitForFunction(() => (document.getElementById("still") as HTMLImageElement).complete, null, WAIT);
    assert.equal(await page.$eval("#still", (img) => (img as HTMLImageElement).naturalWidth), 40, "the <img> loaded");
  } finally {
    await page.close();
  }
  const capability = /signature=(.*)$/.exec(url)![1];
  for (const [asked, status, said] of [
    [`${path.replace("rendered3D", "renderedmpr")}?viewpointposition=0,-700,-785&viewpointlookat=0,-150,-785` +
     `&signature=${capability}`, 403, "not this resource"],
    [`${path.replace(CT.seriesUid, `${CT.seriesUid}.9`)}?signature=${capability}`, 403, "not this resource"],
    [`${path}?signature=${capability.slice(0, -2)}AA`, 401, "not one this gateway made"],
  ] as [string, number, string][]) {
    const answer = await fetch(base + asked);
    const text = await answer.text();
    assert.equal(answer.status, status, `${asked}: ${text}`);
    assert.ok(text.includes(said), `${asked}: ${text}`);
  }
  const brief = await (await sign({ url: `${path}?viewport=32,32&quality=1`, expiresIn: 1 })).json() as { url: string };
  await new Promise((r) => setTimeout(r, 1500));
  const expired = await fetch(base + brief.url);
  assert.equal(expired.status, 401);
  assert.match(await expired.text(), /expired/);
  assert.equal((await sign({ url: path }, "mallory-token")).status, 401, "a token the server refuses gets none");
  assert.equal((await sign({ url: path, expiresIn: 3600 })).status, 400, "longer than 300 s");
});

test("measurements go to the PACS as an SR and come back", async () => {
  const { page } = run;
  await openCt(page);
  await measureOnAxialSlice(page);
  const measured = await pageMeasurements(page);
  assert.equal(measured.length, 1, "the page holds the distance measured");
  await measurementsApplied(page);
  const said = await sayingAfter(page, () => page.click("#pacs-store-measurements"),
                                 /Measurements stored on orthanc: series [0-9.]+/, "the measurements stored");
  const srSeries = /series ([0-9.]+)/.exec(said)![1];
  // What the PACS holds: the same points, measured on the CT series.
  const report = await cliJson<{ measurements: { points: Partial<V>[] }[]; sourceSeriesUid: string }>(["measurements",
    "load", "--pacs", "orthanc", "--study", CT.studyUid, "--series", srSeries]);
  assert.equal(report.sourceSeriesUid, CT.seriesUid);
  assertSamePoints(report.measurements.map((m) => m.points.map(point)), measured, "the report on the PACS");
  // The report as a second reader (dcmjs) reads it: TID 1500's distance on the measured points, in the CT's frame.
  assertReportHoldsTheDistance(await readBack(srSeries), measured[0], (await ctAsStored()).frameOfReferenceUid);

  // Listed again: the report's series; then a new session of the CT, which has no measurements until it reads them.
  const measuredIn = await status(page);
  await listSeries(page);
  assert.match(await openListed(page, /^CT · /), /20 images/);
  assert.match((await page.locator("#pacs-results button", { hasText: /^SR · / }).allTextContents()).join("|"),
               /^SR · cinevol measurements · 1 images$/);
  await newSession(page, measuredIn, "a new session of the CT");
  assert.deepEqual(await pageMeasurements(page), [], "a new session starts without measurements");
  assert.equal(await page.locator("#measurements li").count(), 0);
  await sayingAfter(page, () => openListed(page, /^SR · /), /^1 measurement\(s\) from the report$/, "the report read");
  assertSamePoints(await pageMeasurements(page), measured, "the page's measurement read from the report");
  await waitForText(page, "#measurements", /Distance \d+\.\d mm/);
  assert.equal((await status(page)).error, "");
  await page.screenshot({ path: join(ARTIFACTS, "pacs-5-measurements.png") });
});

test("a DICOM SEG of the study loads as the open volume's labels", async () => {
  const { page } = run;
  const seg = writeSeg(join(scratch, "seg.dcm"));
  await upload(run.orthanc, [seg.file]);
  const ct = await openCt(page);
  const volumeId = await page.inputValue("#volumes");
  await listSeries(page);
  assert.match(await openListed(page, /^SEG · /), /cinevol e2e segmentation · 1 images/);
  // The labels come with the volume: the page opens it again, in a session of its own, and lists them.
  await newSession(page, ct, "a session of the CT with its labels");
  try {
    await page.waitForFunction((n) => document.querySelectorAll("#labels li").length === n, SEG_SEGMENTS.length, WAIT);
  } catch (e) {
    throw new Error(`the labels panel lists "${await page.textContent("#labels")}" (${e})`);
  }
  assert.deepEqual((await page.locator("#labels li").allTextContents()).map((t) => t.trim()),
                   SEG_SEGMENTS.map((s) => `${s.number} ${s.label}`));
  assert.ok(await page.isVisible("#labels-panel"), "the labels panel shows");
  assert.equal(await page.inputValue("#volumes"), volumeId, "the labels are the open volume's");
  // The server's word: every segment with its name, its voxels (the frames lie on the CT's planes and pixels) and
  // its colour (red and green in CIELab).
  const { labels } = await cliJson<{ labels: { source: string; note: string; names: LabelName[] } }>(
    ["volumes", "describe", volumeId]);
  assert.equal(labels.source, `pacs:orthanc/${CT.studyUid}/${SEG.seriesUid}`);
  assert.match(labels.note, /DICOM SEG \(BINARY, 2 segments, 9 frames\)/);
  for (const [i, segment] of SEG_SEGMENTS.entries()) {
    const name = labels.names.find((n) => n.value === segment.number);
    assert.ok(name, `segment ${segment.number} among ${JSON.stringify(labels.names)}`);
    assert.equal(name.name, segment.label);
    assert.equal(Number(name.voxels), seg.voxels[i], `segment ${segment.number}'s voxels`);
    const rgb = [name.color?.r ?? 0, name.color?.g ?? 0, name.color?.b ?? 0];
    assert.ok(rgb.every((c, k) => Math.abs(c - segment.rgb[k]) < 0.1), `segment ${segment.number} is ${rgb}`);
  }
  const shown = await status(page);
  assert.equal(shown.error, "");
  assert.ok(!(await page.isVisible("#error")), "no error line");
  await page.screenshot({ path: join(ARTIFACTS, "pacs-6-seg.png") });
});

/** What dicomweb-client's generic requests answer (private in its types, the way to ask for other resources). */
interface GenericRequests {
  wadoURL: string;
  _httpGetImage(url: string, mediaTypes: { mediaType: string }[], params: object): Promise<ArrayBuffer[]>;
  _httpGetApplicationJson(url: string, params: object): Promise<unknown>;
}

/** The server's sessions and volumes, to compare before and after what should touch neither. */
async function serverHolds(): Promise<{ sessions: number; volumes: string[] }> {
  const s = await cliJson<{ sessions?: unknown[]; volumes?: { id: string }[] }>(["status"]);
  return { sessions: s.sessions?.length ?? 0, volumes: (s.volumes ?? []).map((v) => v.id).sort() };
}

/** A picture decoded by Chromium (createImageBitmap): its size and mean value. */
async function decodedInBrowser(bytes: Buffer, type: string): Promise<{ width: number; height: number; mean: number }> {
  return run.page.evaluate(async ([base64, mime]) => {
    const bitmap = await createImageBitmap(new Blob([Uint8Array.from(atob(base64), (c) => c.charCodeAt(0))],
                                                    { type: mime }));
    const canvas = new OffscreenCanvas(bitmap.width, bitmap.height), context = canvas.getContext("2d")!;
    context.drawImage(bitmap, 0, 0);
    const rgba = context.getImageData(0, 0, bitmap.width, bitmap.height).data;
    let sum = 0;
    for (let i = 0; i < rgba.length; i += 4) sum += rgba[i] + rgba[i + 1] + rgba[i + 2];
    return { width: bitmap.width, height: bitmap.height, mean: sum / (rgba.length * 0.75) };
  }, [bytes.toString("base64"), type] as const);
}

/** `cinevol slice` of the stamped CT (the files Orthanc holds) on the coronal plane the MPR test asks for. */
/** Each URL answered with its status and a message holding its words, and the server left holding what it held. */
async function expectRefusals(held: unknown, cases: [string, number, string][]): Promise<void> {
  for (const [url, status, said] of cases) {
    const answer = await fetch(url);
    const text = await answer.text();
    assert.equal(answer.status, status, `${url}: ${text}`);
    assert.ok(text.includes(said), `${url}: ${text}`);
  }
  assert.deepEqual(await serverHolds(), held, "the refusals left the server as it was");
}

/** `cinevol slice` of the stamped CT's files through a soft-tissue window, with the plane `args` say. */
async function cliSlice(args: string[], name: string): Promise<Buffer> {
  const out = join(ARTIFACTS, `pacs-slice-${name}.png`);
  await promisify(execFile)(CLI, ["slice", "--volume", join(scratch, "stamped"), ...args, "--window", "400",
    "--level", "40", "--no-labels", "--out", out], { timeout: 120_000 });
  return readFileSync(out);
}

/** The mean and largest absolute difference of two pictures' bytes. */
function difference(a: Uint8Array, b: Uint8Array): { mean: number; most: number } {
  let sum = 0, most = 0;
  for (let i = 0; i < a.length; ++i) {
    const d = Math.abs(a[i] - b[i]);
    sum += d;
    most = Math.max(most, d);
  }
  return { mean: sum / a.length, most };
}

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

/** Opens the CT from the PACS list in a new session: its status once a frame of it is painted. */
async function openCt(page: Page): Promise<PageStatus> {
  const before = await status(page);
  await listSeries(page);
  assert.match(await openListed(page, /^CT · /), /20 images/);
  return newSession(page, before, "a new session of the CT");
}

/** Waits for a session other than `before`'s, and a frame of it; fails on an error shown. */
async function newSession(page: Page, before: PageStatus, what: string): Promise<PageStatus> {
  const opened = await until(page, (s) => s.error !== "" || s.sessionId !== before.sessionId, what);
  assert.equal(opened.error, "", what);
  return until(page, (s) => s.framesPainted > opened.framesPainted, `a frame of ${what}`);
}

/** A distance measured across the middle of the axial slice (2x2 layout), half its 500 mm wide. */
async function measureOnAxialSlice(page: Page): Promise<void> {
  await page.click("#layout");
  await page.waitForFunction(() => [...document.querySelectorAll<HTMLImageElement>(".slice img")]
    .every((img) => img.naturalWidth > 0), null, WAIT);
  await page.click("#measure-distance");
  const slice = (await page.locator("#slice-axial img").boundingBox())!;
  const side = Math.min(slice.width, slice.height);
  await page.mouse.click(slice.x + slice.width / 2 - side / 4, slice.y + slice.height / 2);
  await page.mouse.click(slice.x + slice.width / 2 + side / 4, slice.y + slice.height / 2);
  const mm = Number(/Distance (\d+\.\d) mm/.exec(await waitForText(page, "#measurements", /Distance \d+\.\d mm/))![1]);
  assert.ok(Math.abs(mm - 250) < 5, `half the CT's 500 mm wide slice: ${mm} mm`);
  await page.click("#layout");
}

/**
 * The session has the page's measurements: they go in a SendEvents of their
 * own kind, which no frame answers; events go one batch at a time, so a
 * frame answering a drag sent after them comes once they are applied.
 */
async function measurementsApplied(page: Page): Promise<void> {
  const before = await status(page);
  assert.ok((before.eventsByKind.measurements ?? 0) > 0, "the measurement went to the session");
  await drag(page, 4, 0);
  await until(page, (s) => s.eventsSent > before.eventsSent && s.lastFrame !== null &&
              s.lastFrame.lastEventSeq >= s.eventsSent, "a frame answering a drag after the measurement");
}

/** Does `act`, then waits until the page says something matching `pattern` (failing on an error); what it said. */
async function sayingAfter(page: Page, act: () => Promise<unknown>, pattern: RegExp, what: string): Promise<string> {
  const said = (s: PageStatus) => s.messages.filter((m) => pattern.test(m));
  const before = said(await status(page)).length;
  await act();
  const s = await until(page, (t) => t.error !== "" || said(t).length > before, what);
  assert.equal(s.error, "", what);
  return said(s).at(-1)!;
}

/** The page's own measurements (LPS mm), as it saves them with the scene (the Output panel's button). */
async function pageMeasurements(page: Page): Promise<V[][]> {
  const [download] = await Promise.all([page.waitForEvent("download", { timeout: WAIT.timeout }),
                                        page.$eval("#save-scene", (b) => (b as HTMLButtonElement).click())]);
  const scene: { measurements?: { points: Partial<V>[] }[] } = JSON.parse(readFileSync(await download.path(), "utf8"));
  return (scene.measurements ?? []).map((m) => m.points.map(point));
}

const point = (p: Partial<V>): V => ({ x: p.x ?? 0, y: p.y ?? 0, z: p.z ?? 0 });  // proto3 JSON leaves zeros out

function assertSamePoints(got: V[][], want: V[][], what: string): void {
  const said = `${what}: ${JSON.stringify(got)}, measured ${JSON.stringify(want)}`;
  assert.equal(got.length, want.length, said);
  got.forEach((m, i) => {
    assert.equal(m.length, want[i].length, said);
    m.forEach((p, k) => assert.ok(near(p, want[i][k]), said));
  });
}

/** What the CLI prints with --json (proto3 JSON of the server's answer). */
async function cliJson<T>(args: string[]): Promise<T> {
  const { stdout } = await promisify(execFile)(CLI, [...args, "--json", "--server", `127.0.0.1:${run.server.port}`],
                                               { timeout: 30_000 });
  return JSON.parse(stdout) as T;
}

interface LabelName { value?: number; name?: string; voxels?: string; color?: { r?: number; g?: number; b?: number } }

const SEG = { seriesUid: `${CT.studyUid}.7`, sopInstanceUid: `${CT.studyUid}.7.1` };
// A crop of 64 x 64 pixels of the CT's planes from its pixel (224, 224): a square of 32 pixels on planes 4 to 8, a
// disc of radius 12 on planes 11 to 14 (of the 20, in order along their normal), red and green.
const SEG_CROP = { from: 224, size: 64 };
const SEG_SEGMENTS = [
  { number: 1, label: "cinevol square", cielab: dicomLab(53.24, 80.09, 67.2), rgb: [1, 0, 0], planes: [4, 5, 6, 7, 8],
    set: (c: number, r: number) => c >= 8 && c < 40 && r >= 8 && r < 40 },
  { number: 2, label: "cinevol disc", cielab: dicomLab(87.73, -86.18, 83.18), rgb: [0, 1, 0], planes: [11, 12, 13, 14],
    set: (c: number, r: number) => (c - 44) ** 2 + (r - 44) ** 2 <= 144 },
];

/** The SEG of SEG_SEGMENTS on the stamped CT's planes, in its study and frame of reference; each segment's voxels. */
function writeSeg(file: string): { file: string; voxels: number[] } {
  const folder = join(scratch, "stamped");
  const slices = readdirSync(folder).map((f) => ctSlice(join(folder, f)));
  assert.equal(slices.length, 20);
  const o = slices[0].orientation, [rowSpacing, columnSpacing] = slices[0].pixelSpacingMm;
  const normal = [o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5], o[0] * o[4] - o[1] * o[3]];
  const along = (p: Vec3) => p[0] * normal[0] + p[1] * normal[1] + p[2] * normal[2];
  slices.sort((a, b) => along(a.positionMm) - along(b.positionMm));
  // Pixel (c, r) of a plane lies at its position + c column spacings along the row + r row spacings down the column.
  const corner = (p: Vec3) =>
    p.map((v, k) => v + SEG_CROP.from * (columnSpacing * o[k] + rowSpacing * o[3 + k])) as Vec3;
  const frames: SegFrame[] = SEG_SEGMENTS.flatMap((s) => s.planes.map((k) => ({
    segment: s.number, positionMm: corner(slices[k].positionMm), set: s.set })));
  writeFileSync(file, segmentationFile({
    ...SEG, studyUid: CT.studyUid, patientId: CT.patientId, patientName: CT.patientName,
    studyDate: slices[0].studyDate, frameOfReferenceUid: slices[0].frameOfReferenceUid,
    rows: SEG_CROP.size, columns: SEG_CROP.size, orientation: o, pixelSpacingMm: slices[0].pixelSpacingMm,
    sliceSpacingMm: along(slices[1].positionMm) - along(slices[0].positionMm),
  }, SEG_SEGMENTS, frames));
  const crop = [...Array(SEG_CROP.size * SEG_CROP.size).keys()];
  return { file, voxels: SEG_SEGMENTS.map((s) => s.planes.length *
    crop.filter((i) => s.set(i % SEG_CROP.size, Math.floor(i / SEG_CROP.size))).length) };
}

// ---- Read back by a second reader: dcmjs, over WADO-RS from Orthanc ----

const SECONDARY_CAPTURE = "1.2.840.10008.5.1.4.1.1.7", VOLUME_RENDERING_STATE = "1.2.840.10008.5.1.4.1.1.11.9";
const COMPREHENSIVE_3D_SR = "1.2.840.10008.5.1.4.1.1.88.34", EXPLICIT_VR_LITTLE_ENDIAN = "1.2.840.10008.1.2.1";

/** A Part 10 file as dcmjs reads it: its transfer syntax and its data set, naturalized. */
interface ReadBack { transferSyntax: string; data: Naturalized }

/** dicomweb-client on Orthanc's own DICOMweb (XMLHttpRequest over fetch, xhr.ts). */
function orthancClient(): dicomweb.DICOMwebClient {
  (globalThis as { XMLHttpRequest?: unknown }).XMLHttpRequest = FetchXhr;
  return new dicomweb.DICOMwebClient({ url: dicomWeb(run.orthanc), headers: authorization(run.orthanc), verbose: false,
                                       singlepart: false });
}

/**
 * An object of a series cinevol stored in the CT's study, as Orthanc gives it back by WADO-RS (application/dicom,
 * multipart) and dcmjs reads it: the instance `sopInstanceUid`, or the series' only one.
 */
async function readBack(seriesUid: string, sopInstanceUid?: string): Promise<ReadBack> {
  const files = await orthancClient().retrieveSeries({ studyInstanceUID: CT.studyUid, seriesInstanceUID: seriesUid,
                                                       request: {} });
  const read = files.map((part10) => {
    const file = dcmjs.data.DicomMessage.readFile(part10);
    return { transferSyntax: String(file.meta["00020010"]?.Value?.[0] ?? ""),
             data: dcmjs.data.DicomMetaDictionary.naturalizeDataset(file.dict) };
  });
  const found = read.filter((r) => sopInstanceUid === undefined || r.data.SOPInstanceUID === sopInstanceUid);
  assert.equal(found.length, 1, `series ${seriesUid} holds ${read.map((r) => r.data.SOPInstanceUID).join(", ")}`);
  return found[0];
}

/** A naturalized attribute's values or items as a list: dcmjs unwraps a single value, and an empty one is null. */
const all = (value: unknown): unknown[] =>
  value === null || value === undefined ? [] : Array.isArray(value) ? value : [value];
const items = (value: unknown) => all(value) as Naturalized[];
const uidsOf = (references: unknown) => items(references).map((r) => String(r.ReferencedSOPInstanceUID)).sort();

/** A person name's alphabetic group (dcmjs reads PN as { Alphabetic }). */
function personName(value: unknown): string {
  const first = all(value)[0];
  return String(typeof first === "object" && first !== null ? (first as { Alphabetic?: string }).Alphabetic : first);
}

/** The CT as Orthanc holds it (its metadata): its images' SOP Instance UIDs, sorted, and its frame of reference. */
async function ctAsStored(): Promise<{ instances: string[]; frameOfReferenceUid: string }> {
  const metadata = await orthancClient().retrieveSeriesMetadata({ studyInstanceUID: CT.studyUid,
    seriesInstanceUID: CT.seriesUid, request: {} }) as unknown as Record<string, { Value: string[] }>[];
  assert.equal(metadata.length, 20, "the CT's 20 images");
  return { instances: metadata.map((m) => m["00080018"].Value[0]).sort(),
           frameOfReferenceUid: metadata[0]["00200052"].Value[0] };
}

/** The capture files under the CT's patient and study, and its pixels are the still's, as lossless as it says. */
function assertCaptureIsTheStill(capture: ReadBack, still: Pixels): void {
  const d = capture.data;
  assert.equal(d.SOPClassUID, SECONDARY_CAPTURE);
  assert.deepEqual([d.StudyInstanceUID, d.PatientID, personName(d.PatientName)],
                   [CT.studyUid, CT.patientId, CT.patientName], "the CT's study and patient");
  assert.ok(String(d.DerivationDescription).includes(`of series ${CT.seriesUid} `), String(d.DerivationDescription));
  assert.deepEqual([d.Rows, d.Columns], [still.height, still.width], "the still's size");
  assert.deepEqual([d.SamplesPerPixel, d.PhotometricInterpretation, d.PlanarConfiguration, d.BitsAllocated],
                   [3, "RGB", 0, 8]);
  assert.equal(capture.transferSyntax, EXPLICIT_VR_LITTLE_ENDIAN, "the pixels as they were stored");
  const rgb = still.channels === 3 ? still.pixels : still.pixels.filter((_, i) => i % 4 !== 3);
  const stored = new Uint8Array(all(d.PixelData)[0] as ArrayBuffer);
  assert.ok(stored.length === rgb.length || stored.length === rgb.length + 1, `${stored.length} bytes of pixels`);
  const { most } = difference(stored.subarray(0, rgb.length), rgb);
  const lossy = d.LossyImageCompression === "01";
  assert.ok(most <= (lossy ? 1 : 0), `the capture's pixels and the still's differ by up to ${most} levels` +
            ` (Lossy Image Compression ${String(d.LossyImageCompression)})`);
}

/**
 * The state presents the CT's images (input and references), names the capture as its rendered image, and holds
 * the camera of the scene it gives back: Viewpoint Position, LookAt Point and Up Direction within 1e-3 mm.
 */
function assertStatePresentsTheStill(state: ReadBack, ct: { instances: string[]; frameOfReferenceUid: string },
                                     capture: { series: string; instance: string },
                                     camera: { eye: V; target: V; up: V }): void {
  const d = state.data;
  assert.equal(d.SOPClassUID, VOLUME_RENDERING_STATE, "no labels: the plain kind");
  assert.deepEqual([d.Modality, d.StudyInstanceUID, d.PatientID, d.FrameOfReferenceUID],
                   ["PR", CT.studyUid, CT.patientId, ct.frameOfReferenceUid], "the CT's study, patient and frame");
  const [input] = items(d.VolumetricPresentationInputSetSequence);
  assert.equal(input?.PresentationInputType, "VOLUME");
  assert.deepEqual(uidsOf(input.ReferencedImageSequence), ct.instances, "the input: the CT's images");
  const series = (uid: string) => items(d.ReferencedSeriesSequence).find((s) => s.SeriesInstanceUID === uid);
  assert.deepEqual(uidsOf(series(CT.seriesUid)?.ReferencedInstanceSequence), ct.instances, "the CT series referenced");
  assert.deepEqual(uidsOf(series(capture.series)?.ReferencedInstanceSequence), [capture.instance], "the capture's");
  const rendered = items(d.RenderedImageReferenceSequence);
  assert.deepEqual(rendered.map((r) => [r.ReferencedSOPClassUID, r.ReferencedSOPInstanceUID]),
                   [[SECONDARY_CAPTURE, capture.instance]], "the rendered image: the capture");
  for (const [keyword, want] of [["ViewpointPosition", camera.eye], ["ViewpointLookAtPoint", camera.target],
                                 ["ViewpointUpDirection", camera.up]] as const) {
    const got = all(d[keyword]).map(Number);
    assert.ok(got.length === 3 && got.every((v, k) => Math.abs(v - [want.x, want.y, want.z][k]) <= 1e-3),
              `${keyword} ${got}, the scene's ${JSON.stringify(want)}`);
  }
  assert.ok(near(point(camera.eye), STILL_SCENE.camera.eye) && near(point(camera.target), STILL_SCENE.camera.target),
            `the still's scene's camera: ${JSON.stringify(camera)}`);
}

/** `cinevol pacs load --presentation UID --scene-out F`: the camera of the scene the state gives back (LPS mm). */
async function presentedCamera(stateSeries: string, stateUid: string): Promise<{ eye: V; target: V; up: V }> {
  const file = join(scratch, "presented-scene.json");
  await promisify(execFile)(CLI, ["pacs", "load", "--pacs", "orthanc", "--study", CT.studyUid, "--series", stateSeries,
    "--presentation", stateUid, "--scene-out", file, "--server", `127.0.0.1:${run.server.port}`], { timeout: 60_000 });
  const scene = JSON.parse(readFileSync(file, "utf8")) as { frame?: string; camera: Record<"eye" | "target" | "up",
                                                                                         Partial<V>> };
  assert.equal(scene.frame, "PATIENT_LPS");
  return { eye: point(scene.camera.eye), target: point(scene.camera.target), up: point(scene.camera.up) };
}

/**
 * TID 1500 as dcmjs reads it: Imaging Measurements holds one Measurement Group whose Length (SCT 410668003, mm) is
 * the distance between `points` and is inferred from a SCOORD3D polyline on them in the CT's frame of reference, all
 * within 0.01 mm.
 */
function assertReportHoldsTheDistance(report: ReadBack, points: V[], frameOfReferenceUid: string): void {
  const d = report.data;
  assert.equal(d.SOPClassUID, COMPREHENSIVE_3D_SR);
  assert.deepEqual([d.StudyInstanceUID, d.PatientID], [CT.studyUid, CT.patientId], "the CT's study and patient");
  const code = (item: Naturalized) => items(item.ConceptNameCodeSequence)[0]?.CodeValue;
  const children = (item: Naturalized, valueType: string, concept?: string) => items(item.ContentSequence)
    .filter((c) => c.ValueType === valueType && (concept === undefined || code(c) === concept));
  assert.deepEqual([d.ValueType, code(d)], ["CONTAINER", "126000"], "an Imaging Measurement Report");
  const [imaging, ...more] = children(d, "CONTAINER", "126010");
  assert.ok(imaging && more.length === 0, "one Imaging Measurements container");
  const groups = children(imaging, "CONTAINER", "125007");
  assert.equal(groups.length, 1, "one Measurement Group: the one distance");
  const [length] = children(groups[0], "NUM", "410668003");
  assert.ok(length, "the group's Length");
  const [value] = items(length.MeasuredValueSequence);
  assert.equal(items(value?.MeasurementUnitsCodeSequence)[0]?.CodeValue, "mm");
  const [a, b] = points;
  const distance = Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z);
  assert.ok(Math.abs(Number(value.NumericValue) - distance) <= 0.01,
            `Length ${value.NumericValue} mm; measured ${distance} mm`);
  const [coordinates] = children(length, "SCOORD3D");
  assert.ok(coordinates, "the Length's SCOORD3D");
  assert.deepEqual([coordinates.RelationshipType, coordinates.GraphicType], ["INFERRED FROM", "POLYLINE"]);
  assert.equal(coordinates.ReferencedFrameOfReferenceUID, frameOfReferenceUid, "the CT's frame of reference");
  const data = all(coordinates.GraphicData).map(Number), want = points.flatMap((p) => [p.x, p.y, p.z]);
  assert.ok(data.length === want.length && data.every((v, k) => Math.abs(v - want[k]) <= 0.01),
            `Graphic Data ${data}; measured ${want}`);
}

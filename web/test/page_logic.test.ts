import assert from "node:assert/strict";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import { SliceAxis, VolumeInfoSchema, VolumePlacementSchema } from "../gen/cinevol/v1/service_pb.js";
import { readAddress, sessionQuery } from "../src/address.js";
import {
  centre, cropFromFractions, directionToPatient, directionToVolume, patientBox, placementOf, samePlacement,
  slicePlaneOutline, spacingAlong, toPatient, toVolume, type Placement,
} from "../src/placement.js";
import { messageToShow } from "../src/messages.js";
import { fusedStart, glowOf } from "../src/fusion_panel.js";
import { moviePath } from "../src/movie_panel.js";
import { MotionToPhoton, percentile, Rate } from "../src/stats.js";
import { plainWords, signInWords, tokenRefused } from "../src/words.js";

test("the address: volume and preset in the query, the token only from the fragment", () => {
  const a = readAddress("?volume=phantom%3Ahead&preset=ct-bone&token=leak", "#token=s3cret");
  assert.deepEqual(a, { volume: "phantom:head", preset: "ct-bone", fuse: undefined, alignByPatient: false,
                        session: undefined, token: "s3cret", grant: undefined, iid: undefined });
  const fused = readAddress("?volume=ct&fuse=pet&align=patient", "");
  assert.equal(fused.fuse, "pet");
  assert.equal(fused.alignByPatient, true);
  assert.equal(readAddress("?volume=ct&fuse=pet&align=yes", "").alignByPatient, false, "only align=patient aligns");
  assert.equal(readAddress("", "").token, undefined);
  assert.equal(sessionQuery("?volume=v", "abc"), "?volume=v&session=abc");
});

test("percentiles by nearest rank", () => {
  const samples = Array.from({ length: 100 }, (_, i) => i + 1);
  assert.equal(percentile(samples, 0.5), 50);
  assert.equal(percentile(samples, 0.95), 95);
  assert.ok(Number.isNaN(percentile([], 0.5)));
});

test("motion-to-photon: a painted frame closes every event it includes, from each one's input", () => {
  const m = new MotionToPhoton();
  m.sent(1n, 100);
  m.sent(2n, 110);
  m.sent(3n, 120);
  m.painted(2n, 150);
  assert.deepEqual(m.samples, [50, 40]);
  m.reset();
  m.painted(3n, 200);
  assert.equal(m.samples.length, 2, "an attach forgets what was pending");
});

test("rates count over their window", () => {
  const r = new Rate(1000);
  r.add(0, 500);
  r.add(500, 500);
  assert.equal(r.perSecond(900), 1000);
  assert.equal(r.perSecond(1600), 0);
});

test("refusals come in plain words with the server's own message", () => {
  assert.match(plainWords(new ConnectError("no such token", Code.Unauthenticated)), /did not accept your token.*no such token/);
  assert.match(plainWords(new ConnectError("session abc belongs to alice", Code.PermissionDenied)), /another user/);
  assert.match(plainWords(new Error("boom")), /failed/);
});

/** 11 x 21 x 31 voxels at the origin (LPS unless `direction` says otherwise). */
const placed = (spacing: [number, number, number], direction = [1, 0, 0, 0, 1, 0, 0, 0, 1],
                origin = { x: 0, y: 0, z: 0 }): Placement =>
  ({ direction, originMm: origin, spacingMm: { x: spacing[0], y: spacing[1], z: spacing[2] }, dims: { x: 11, y: 21, z: 31 } });

test("the patient box of an LPS volume and of one flipped along x", () => {
  assert.deepEqual(patientBox(placed([1, 1, 2])), { min: { x: 0, y: 0, z: 0 }, max: { x: 10, y: 20, z: 60 } });
  const flipped = placed([1, 1, 2], [-1, 0, 0, 0, 1, 0, 0, 0, 1]);
  assert.deepEqual(patientBox(flipped).min, { x: -10, y: 0, z: 0 });
  const crop = cropFromFractions(patientBox(flipped), { x: 0, y: 0.5, z: 0 }, { x: 1, y: 1, z: 0.5 });
  assert.deepEqual(crop, { center: { x: -5, y: 15, z: 15 }, size: { x: 10, y: 10, z: 30 } });
  assert.deepEqual(toPatient(flipped, { x: 0, y: 0, z: 0 }), { x: -5, y: 10, z: 30 });
  assert.deepEqual(centre(flipped), { x: -5, y: 10, z: 30 }, "the volume-centred frame's origin");
});

test("a state's placement is read whole or not at all, and compared by value", () => {
  const message = create(VolumePlacementSchema, { direction: [0, 1, 0, 1, 0, 0, 0, 0, 1], originMm: { x: 1, y: 2, z: 3 },
                                                  spacingMm: { x: 0.5, y: 0.5, z: 2 }, dims: { x: 4, y: 5, z: 6 } });
  const p = placementOf(message)!;
  assert.deepEqual(p, { direction: [0, 1, 0, 1, 0, 0, 0, 0, 1], originMm: { x: 1, y: 2, z: 3 },
                        spacingMm: { x: 0.5, y: 0.5, z: 2 }, dims: { x: 4, y: 5, z: 6 } });
  assert.ok(samePlacement(p, placementOf(create(VolumePlacementSchema, message))));
  const { spacingMm, dims } = message;
  const moved = create(VolumePlacementSchema, { direction: message.direction, originMm: { x: 1, y: 2, z: 4 }, spacingMm, dims });
  assert.ok(!samePlacement(p, placementOf(moved)));
  assert.equal(placementOf(create(VolumePlacementSchema, { originMm: message.originMm, spacingMm, dims })), undefined,
               "no direction: no placement (a server older than the page), never a guessed identity");
  assert.equal(placementOf(undefined), undefined);
});

test("slice pixels and patient positions map both ways; distances and angles", async () => {
  const { slicePixelToPatient, patientToSlicePixel, distanceMm, angleDeg, measurementText, projectToView } =
    await import("../src/measure.js");
  const { SliceImageSchema } = await import("../gen/cinevol/v1/service_pb.js");
  // An axial slice in radiological convention: rows run to the patient's left (+x), columns to posterior (+y).
  const image = create(SliceImageSchema, { originMm: { x: -100, y: -50, z: 12 }, rowDirection: { x: 1, y: 0, z: 0 },
    columnDirection: { x: 0, y: 1, z: 0 }, rowSpacingMm: 0.5, columnSpacingMm: 0.8, width: 400, height: 125 });
  const p = slicePixelToPatient(image, 10, 20);
  assert.deepEqual(p, { x: -95, y: -34, z: 12 });
  const back = patientToSlicePixel(image, { x: -95, y: -34, z: 15 });
  assert.ok(Math.abs(back.column - 10) < 1e-9 && Math.abs(back.row - 20) < 1e-9 && Math.abs(Math.abs(back.offPlaneMm) - 3) < 1e-9);
  assert.equal(distanceMm({ x: 0, y: 0, z: 0 }, { x: 3, y: 4, z: 0 }), 5);
  assert.ok(Math.abs(angleDeg({ x: 1, y: 0, z: 0 }, { x: 0, y: 0, z: 0 }, { x: 0, y: 1, z: 0 }) - 90) < 1e-9);
  assert.equal(measurementText([{ x: 0, y: 0, z: 0 }, { x: 0, y: 0, z: 42.5 }]), "42.5 mm");
  const cam = { eye: { x: 0, y: -100, z: 0 }, target: { x: 0, y: 0, z: 0 }, up: { x: 0, y: 0, z: 1 }, fovYDeg: 90 };
  assert.deepEqual(projectToView(cam, { x: 0, y: 0, z: 0 }, 200, 100), { x: 100, y: 50 });
  const right = projectToView(cam, { x: 50, y: 0, z: 0 }, 200, 100)!;
  assert.ok(right.x > 100 && Math.abs(right.y - 50) < 1e-9, "the patient's left (+x) on the right from the front");
  assert.equal(projectToView(cam, { x: 0, y: -200, z: 0 }, 200, 100), null);
});

test("patient and volume-centred frames are each other's inverse; spacing along a patient axis", () => {
  const volume = placed([0.5, 1, 2], [0, 1, 0, 1, 0, 0, 0, 0, 1], { x: 3, y: -4, z: 5 });
  const p = { x: 7, y: -2, z: 40 };
  const back = toPatient(volume, toVolume(volume, p));
  assert.ok(Math.abs(back.x - p.x) + Math.abs(back.y - p.y) + Math.abs(back.z - p.z) < 1e-9);
  const d = { x: 0.6, y: 0, z: 0.8 }, turned = directionToVolume(volume, directionToPatient(volume, d));
  assert.ok(Math.abs(turned.x - d.x) + Math.abs(turned.y - d.y) + Math.abs(turned.z - d.z) < 1e-12);
  assert.deepEqual(directionToPatient(volume, { x: 1, y: 0, z: 0 }), { x: 0, y: 1, z: 0 }, "index axis i runs along P");
  assert.equal(spacingAlong(volume, "x"), 1, "index axis j runs along patient x");
  assert.equal(spacingAlong(volume, "y"), 0.5);
});

test("a DICOM identity fills the corners people expect", async () => {
  const { personName, studyDate, identityCorners } = await import("../src/identity.js");
  const { PatientIdentitySchema } = await import("../gen/cinevol/v1/service_pb.js");
  assert.equal(personName("Doe^John^^Dr"), "Doe, John Dr");
  assert.equal(personName("Yamada^Tarou=\u5c71\u7530^\u592a\u90ce"), "Yamada, Tarou");
  assert.equal(personName("ANONYMOUS"), "ANONYMOUS");
  assert.equal(studyDate("20091203"), "2009-12-03");
  assert.equal(studyDate("2009"), "2009");
  const corners = identityCorners(create(PatientIdentitySchema, {
    patientName: "My Patient Name", patientId: "123456789", studyDate: "20091203", seriesDescription: "T1 axial" }));
  assert.deepEqual(corners, { topLeft: ["My Patient Name", "ID 123456789"], topRight: ["2009-12-03", "T1 axial"] });
});

test("a slice plane's outline is where it cuts the volume's box, in order around it", async () => {
  // 11 x 21 x 31 voxels of 1 x 1 x 2 mm at the origin, LPS: the box spans 10 x 20 x 60 mm.
  const volume = placed([1, 1, 2]);
  const axial = slicePlaneOutline(volume, "z", 30);
  assert.equal(axial.length, 4);
  for (const p of axial) assert.equal(p.z, 30);
  const xs = axial.map((p) => p.x).sort((a, b) => a - b), ys = axial.map((p) => p.y).sort((a, b) => a - b);
  assert.deepEqual([xs[0], xs[3], ys[0], ys[3]], [0, 10, 0, 20]);
  for (let i = 0; i < 4; ++i) {  // neighbours share an edge of the rectangle: no diagonal
    const p = axial[i], q = axial[(i + 1) % 4];
    assert.ok(p.x === q.x || p.y === q.y, `corner ${i} to ${i + 1} runs along an edge`);
  }
  assert.deepEqual(slicePlaneOutline(volume, "x", 11), [], "beyond the box: nothing");
  // RAS-stored: the plane still lies where the patient coordinate says.
  const ras = placed([1, 1, 2], [-1, 0, 0, 0, -1, 0, 0, 0, 1]);
  const sagittal = slicePlaneOutline(ras, "x", -5);
  assert.equal(sagittal.length, 4);
  for (const p of sagittal) assert.equal(p.x, -5);
});

test("one message at a time: an error before news, news before waiting", () => {
  assert.deepEqual(messageToShow({ error: "refused", banner: "reconnected", waiting: "Waiting for the first frame…" }),
                   { kind: "error", text: "refused" });
  assert.deepEqual(messageToShow({ error: "", banner: "reconnected", waiting: "Waiting…" }), { kind: "banner", text: "reconnected" });
  assert.deepEqual(messageToShow({ error: "", banner: "", waiting: "Waiting…" }), { kind: "banner", text: "Waiting…" });
  assert.equal(messageToShow({ error: "", banner: "", waiting: "" }), null);
});

test("a server that needs a token says so in words; a token it refuses is named as such", () => {
  const needed = new ConnectError("this server needs a token: send the metadata 'authorization: Bearer <token>'",
                                  Code.Unauthenticated);
  assert.ok(tokenRefused(needed));
  assert.ok(!tokenRefused(new ConnectError("down", Code.Unavailable)), "an unreachable server asks for no token");
  assert.match(signInWords(needed, false), /needs a token: enter yours/);
  assert.doesNotMatch(signInWords(needed, false), /metadata/, "the server's words for programs are not shown");
  assert.match(signInWords(new ConnectError("the bearer token is not valid", Code.Unauthenticated), true),
               /did not accept your token.*not valid/);
});

test("a movie's path from the page's choice: a whole turn, a sweep across an axis, or the phases", () => {
  assert.deepEqual(moviePath("orbit"), { case: "orbitDegrees", value: 360 });
  assert.deepEqual(moviePath("sweep-coronal"), { case: "sweep", value: SliceAxis.CORONAL });
  assert.deepEqual(moviePath("phases"), { case: "phases", value: true });
});

test("a second volume glows above SUVbw 2.5 where it has SUVbw, else over the top 70% of its range", () => {
  const pet = glowOf({ minValue: 0, maxValue: 40000, suvFactor: 2.5e-4 });
  assert.deepEqual(pet.points.map((p) => [p.value, p.opacity]), [[2.5, 0], [10, 0.4]]);
  const mr = glowOf({ minValue: 100, maxValue: 1100, suvFactor: 0 });
  assert.deepEqual(mr.points.map((p) => [p.value, p.opacity]), [[400, 0], [1100, 0.4]]);
  assert.ok(mr.points[1].emission!.r > 0, "it emits");
  const start = fusedStart(create(VolumeInfoSchema, { id: "pet", maxValue: 40000, suvFactor: 2.5e-4 }), true);
  assert.equal(start.volumeId, "pet");
  assert.ok(start.suv && start.alignByPatient);
  assert.equal(start.overlay?.opacity, 0.5);
});

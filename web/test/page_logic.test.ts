import assert from "node:assert/strict";
import { test } from "node:test";
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import { VolumeInfoSchema } from "../gen/cinevol/v1/service_pb.js";
import { readAddress, sessionQuery } from "../src/address.js";
import { cropFromFractions, patientBox, toPatient } from "../src/geometry.js";
import { MotionToPhoton, percentile, Rate } from "../src/stats.js";
import { plainWords } from "../src/words.js";

test("the address: volume and preset in the query, the token only from the fragment", () => {
  const a = readAddress("?volume=phantom%3Ahead&preset=ct-bone&token=leak", "#token=s3cret");
  assert.deepEqual(a, { volume: "phantom:head", preset: "ct-bone", session: undefined, token: "s3cret" });
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

test("the patient box of an LPS volume and of one flipped along x", () => {
  const volume = create(VolumeInfoSchema, { dims: { x: 11, y: 21, z: 31 }, spacingMm: { x: 1, y: 1, z: 2 },
                                            originMm: { x: 0, y: 0, z: 0 } });
  assert.deepEqual(patientBox(volume), { min: { x: 0, y: 0, z: 0 }, max: { x: 10, y: 20, z: 60 } });
  volume.direction = [-1, 0, 0, 0, 1, 0, 0, 0, 1];
  assert.deepEqual(patientBox(volume).min, { x: -10, y: 0, z: 0 });
  const crop = cropFromFractions(patientBox(volume), { x: 0, y: 0.5, z: 0 }, { x: 1, y: 1, z: 0.5 });
  assert.deepEqual(crop, { center: { x: -5, y: 15, z: 15 }, size: { x: 10, y: 10, z: 30 } });
  assert.deepEqual(toPatient(volume, false, { x: 0, y: 0, z: 0 }), { x: -5, y: 10, z: 30 });
});

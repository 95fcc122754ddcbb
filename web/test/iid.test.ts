// IHE Invoke Image Display launch addresses (src/iid.ts): what the gateway refuses with 400, and what the page opens.
import assert from "node:assert/strict";
import { test } from "node:test";
import { readAddress } from "../src/address.js";
import { readIid, type IidRequest } from "../src/iid.js";

const read = (query: string) => readIid(new URLSearchParams(query));

test("a study launch names its studies by UID or accession number, the first opened", () => {
  const study = read("requestType=STUDY&studyUID=1.2.3,1.2.4&viewerType=IHE_BIR&diagnosticQuality=true") as IidRequest;
  assert.equal(study.requestType, "STUDY");
  assert.deepEqual(study.studyUids, ["1.2.3", "1.2.4"]);
  const byAccession = read("requestType=STUDY&accessionNumber=ACC-1&keyImagesOnly=false&pacs=main") as IidRequest;
  assert.deepEqual(byAccession.accessionNumbers, ["ACC-1"]);
  assert.equal(byAccession.pacs, "main");
});

test("a patient launch takes the CX value's ID and keeps its issuer", () => {
  const patient = read(`requestType=PATIENT&patientID=${encodeURIComponent("12345^^^&1.2.3.4&ISO")}` +
                       "&mostRecentResults=1") as IidRequest;
  assert.equal(patient.patientId, "12345");
  assert.equal(patient.issuer, "&1.2.3.4&ISO");
});

test("a malformed launch is refused naming the parameter", () => {
  const refusals: [string, RegExp][] = [
    ["", /requestType/], ["requestType=SERIES&studyUID=1.2", /requestType: 'SERIES'/],
    ["requestType=study&studyUID=1.2", /requestType/], ["requestType=STUDY", /give studyUID or accessionNumber/],
    ["requestType=STUDY&studyUID=1.2.x", /studyUID: '1.2.x'/], ["requestType=PATIENT", /patientID/],
    ["requestType=STUDY&studyUID=1.2&viewerType=FANCY", /viewerType/],
    ["requestType=STUDY&studyUID=1.2&diagnosticQuality=yes", /diagnosticQuality/],
    ["requestType=PATIENT&patientID=1&mostRecentResults=0", /mostRecentResults/],
    ["requestType=STUDY&studyUID=1.2&pacs=..%2F", /pacs/],
    [`requestType=STUDY&studyUID=${Array.from({ length: 17 }, (_, i) => `1.${i}`).join(",")}`, /at most 16/],
  ];
  for (const [query, reason] of refusals) assert.match(read(query) as string, reason, query);
});

test("the page reads a launch only at the IID paths", () => {
  assert.equal(readAddress("?requestType=STUDY&studyUID=1.2", "", "/iid").iid?.studyUids[0], "1.2");
  assert.equal(readAddress("?requestType=STUDY&studyUID=1.2", "", "/IHEInvokeImageDisplay").iid?.requestType, "STUDY");
  assert.equal(readAddress("?requestType=STUDY&studyUID=1.2", "", "/").iid, undefined);
});

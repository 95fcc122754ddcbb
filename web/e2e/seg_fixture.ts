// A DICOM SEG for the page's PACS test, written byte by byte (node has no
// dcmseg): Part 10, explicit VR little endian, BINARY, one frame a plane and
// segment, with the attributes server/io/readers/seg_reader.cpp reads (Segment
// Sequence with labels and CIELab colours; Plane Orientation and Pixel Measures
// shared, Plane Position and Segment Identification per frame) and those a
// PACS files it by (patient, study, series, instance, modality SEG). Also: a
// CT file's geometry, read with DCMTK's dcmdump.
import { execFileSync } from "node:child_process";

const SEGMENTATION_STORAGE = "1.2.840.10008.5.1.4.1.1.66.4";
const EXPLICIT_VR_LITTLE_ENDIAN = "1.2.840.10008.1.2.1";
// VRs whose length takes 4 bytes after 2 reserved ones (PS3.5 7.1.2).
const LONG_VRS = new Set(["OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"]);

export type Vec3 = [number, number, number];

/** What the SEG says of where it lies and whom it belongs to. */
export interface SegGeometry {
  studyUid: string; seriesUid: string; sopInstanceUid: string; patientId: string; patientName: string;
  studyDate: string; frameOfReferenceUid: string;
  rows: number; columns: number;
  orientation: number[];            // Image Orientation (Patient): along a row, then down a column
  pixelSpacingMm: [number, number];  // between rows, between columns
  sliceSpacingMm: number;
}

export interface SegSegment { number: number; label: string; cielab: Vec3 }  // cielab: DICOM's scaled 16-bit values
export interface SegFrame { segment: number; positionMm: Vec3; set: (column: number, row: number) => boolean }

/** The SEG file's bytes. */
export function segmentationFile(g: SegGeometry, segments: SegSegment[], frames: SegFrame[]): Buffer {
  const pixels = g.rows * g.columns, bits = Buffer.alloc(Math.ceil((frames.length * pixels) / 8));
  frames.forEach((frame, f) => {
    for (let r = 0; r < g.rows; ++r) {
      for (let c = 0; c < g.columns; ++c) {
        const at = f * pixels + r * g.columns + c;  // PS3.5 8.1.1: frames back to back, the first pixel the lowest bit
        if (frame.set(c, r)) bits[at >> 3] |= 1 << (at & 7);
      }
    }
  });
  const code = (value: string, scheme: string, meaning: string) =>
    [[text(0x0008, 0x0100, "SH", value), text(0x0008, 0x0102, "SH", scheme), text(0x0008, 0x0104, "LO", meaning)]];
  const data = Buffer.concat([
    text(0x0008, 0x0008, "CS", "DERIVED\\PRIMARY"),
    text(0x0008, 0x0016, "UI", SEGMENTATION_STORAGE),
    text(0x0008, 0x0018, "UI", g.sopInstanceUid),
    text(0x0008, 0x0020, "DA", g.studyDate),
    text(0x0008, 0x0060, "CS", "SEG"),
    text(0x0008, 0x103e, "LO", "cinevol e2e segmentation"),
    text(0x0010, 0x0010, "PN", g.patientName),
    text(0x0010, 0x0020, "LO", g.patientId),
    text(0x0020, 0x000d, "UI", g.studyUid),
    text(0x0020, 0x000e, "UI", g.seriesUid),
    text(0x0020, 0x0011, "IS", "9902"),
    text(0x0020, 0x0013, "IS", "1"),
    text(0x0020, 0x0052, "UI", g.frameOfReferenceUid),
    us(0x0028, 0x0002, 1),
    text(0x0028, 0x0004, "CS", "MONOCHROME2"),
    text(0x0028, 0x0008, "IS", String(frames.length)),
    us(0x0028, 0x0010, g.rows),
    us(0x0028, 0x0011, g.columns),
    us(0x0028, 0x0100, 1), us(0x0028, 0x0101, 1), us(0x0028, 0x0102, 0), us(0x0028, 0x0103, 0),
    text(0x0062, 0x0001, "CS", "BINARY"),
    sequence(0x0062, 0x0002, segments.map((s) => [
      sequence(0x0062, 0x0003, code("91723000", "SCT", "Anatomical Structure")),
      us(0x0062, 0x0004, s.number),
      text(0x0062, 0x0005, "LO", s.label),
      text(0x0062, 0x0008, "CS", "MANUAL"),
      us(0x0062, 0x000d, ...s.cielab),
      sequence(0x0062, 0x000f, code("85756007", "SCT", "Tissue")),
    ])),
    text(0x0070, 0x0080, "CS", "SEGMENTATION"),
    sequence(0x5200, 0x9229, [[  // shared functional groups
      sequence(0x0020, 0x9116, [[text(0x0020, 0x0037, "DS", g.orientation.map(ds).join("\\"))]]),
      sequence(0x0028, 0x9110, [[text(0x0018, 0x0050, "DS", ds(g.sliceSpacingMm)),
                                  text(0x0018, 0x0088, "DS", ds(g.sliceSpacingMm)),
                                  text(0x0028, 0x0030, "DS", g.pixelSpacingMm.map(ds).join("\\"))]]),
    ]]),
    sequence(0x5200, 0x9230, frames.map((frame) => [  // per-frame functional groups
      sequence(0x0020, 0x9113, [[text(0x0020, 0x0032, "DS", frame.positionMm.map(ds).join("\\"))]]),
      sequence(0x0062, 0x000a, [[us(0x0062, 0x000b, frame.segment)]]),
    ])),
    element(0x7fe0, 0x0010, "OB", bits),
  ]);
  const meta = Buffer.concat([
    element(0x0002, 0x0001, "OB", Buffer.from([0, 1])),
    text(0x0002, 0x0002, "UI", SEGMENTATION_STORAGE),
    text(0x0002, 0x0003, "UI", g.sopInstanceUid),
    text(0x0002, 0x0010, "UI", EXPLICIT_VR_LITTLE_ENDIAN),
    text(0x0002, 0x0012, "UI", "2.25.3410501999"),
  ]);
  const groupLength = Buffer.alloc(4);
  groupLength.writeUInt32LE(meta.length);
  const preamble = Buffer.concat([Buffer.alloc(128), Buffer.from("DICM")]);
  return Buffer.concat([preamble, element(0x0002, 0x0000, "UL", groupLength), meta, data]);
}

/** DICOM's scaled CIELab (PS3.3 C.10.7.1.1) of L* in [0, 100], a* and b* in [-128, 127]. */
export const dicomLab = (l: number, a: number, b: number): Vec3 =>
  [Math.round((l * 65535) / 100), Math.round(((a + 128) * 65535) / 255), Math.round(((b + 128) * 65535) / 255)];

/** What a SEG needs of a CT file: its plane's position and orientation, pixel spacing, date, frame of reference. */
export interface CtSlice {
  positionMm: Vec3; orientation: number[]; pixelSpacingMm: [number, number]; rows: number; columns: number;
  studyDate: string; frameOfReferenceUid: string;
}

export function ctSlice(file: string): CtSlice {
  const dump = execFileSync("/usr/bin/dcmdump", ["-q", "+P", "0020,0032", "+P", "0020,0037", "+P", "0028,0030",
    "+P", "0028,0010", "+P", "0028,0011", "+P", "0008,0020", "+P", "0020,0052", file], { encoding: "utf8" });
  const value = (tag: string) => {
    const line = dump.split("\n").find((l) => l.startsWith(`(${tag})`));
    const found = line && /^\(\S+\) \S\S (?:\[([^\]]*)\]|(\d+))/.exec(line);
    if (!found) throw new Error(`${file}: dcmdump shows no (${tag}): ${dump}`);
    return found[1] ?? found[2];
  };
  const numbers = (tag: string) => value(tag).split("\\").map(Number);
  return { positionMm: numbers("0020,0032") as Vec3, orientation: numbers("0020,0037"),
           pixelSpacingMm: numbers("0028,0030") as [number, number], rows: Number(value("0028,0010")),
           columns: Number(value("0028,0011")), studyDate: value("0008,0020"),
           frameOfReferenceUid: value("0020,0052") };
}

/** A DS value of at most 16 characters. */
function ds(v: number): string {
  for (let digits = 12; digits > 3; --digits) {
    const s = String(Number(v.toPrecision(digits)));
    if (s.length <= 16) return s;
  }
  throw new Error(`${v} does not fit a DS`);
}

function element(group: number, number: number, vr: string, value: Buffer): Buffer {
  const long = LONG_VRS.has(vr), header = Buffer.alloc(long ? 12 : 8);
  header.writeUInt16LE(group, 0);
  header.writeUInt16LE(number, 2);
  header.write(vr, 4, "latin1");
  if (long) header.writeUInt32LE(value.length, 8);
  else header.writeUInt16LE(value.length, 6);
  return Buffer.concat([header, value]);
}

/** A text value padded to even length: UIDs with a NUL, the rest with a space. */
function text(group: number, number: number, vr: string, value: string): Buffer {
  const padded = value.length % 2 === 0 ? value : value + (vr === "UI" ? "\0" : " ");
  return element(group, number, vr, Buffer.from(padded, "latin1"));
}

function us(group: number, number: number, ...values: number[]): Buffer {
  const bytes = Buffer.alloc(2 * values.length);
  values.forEach((v, i) => bytes.writeUInt16LE(v, 2 * i));
  return element(group, number, "US", bytes);
}

/** A sequence of defined length, each item its elements (in ascending tag order). */
function sequence(group: number, number: number, items: Buffer[][]): Buffer {
  return element(group, number, "SQ", Buffer.concat(items.map((parts) => {
    const body = Buffer.concat(parts), header = Buffer.alloc(8);
    header.writeUInt16LE(0xfffe, 0);
    header.writeUInt16LE(0xe000, 2);
    header.writeUInt32LE(body.length, 4);
    return Buffer.concat([header, body]);
  })));
}

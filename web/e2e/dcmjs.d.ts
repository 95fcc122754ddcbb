// The part of dcmjs (npm, no types of its own) the end-to-end tests use to read back what cinevol writes: a Part 10
// file parsed, its data set in DICOM JSON (PS3.18 F.2) and naturalized (keywords for tags, single values unwrapped).
declare module "dcmjs" {
  /** DICOM JSON: each attribute by its tag (8 hex digits), its VR and its values. */
  export type DicomJson = Record<string, { vr: string; Value?: unknown[] }>;
  /** A naturalized data set: attributes by keyword (tags dcmjs does not know by their hex), sequences as arrays. */
  export type Naturalized = Record<string, unknown>;
  const dcmjs: {
    data: {
      DicomMessage: { readFile(part10: ArrayBuffer): { meta: DicomJson; dict: DicomJson } };
      DicomMetaDictionary: { naturalizeDataset(dataset: DicomJson): Naturalized };
    };
  };
  export default dcmjs;
}

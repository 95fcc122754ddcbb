// A DICOM volume's patient, study and series for the corners of the 3D view
// (the desktop viewer's twin is client-cpp/viewer/reading_view.h). Shown on
// the page only: never sent anywhere, never logged.
import type { PatientIdentity } from "../gen/cinevol/v1/service_pb.js";

/** The top corners (the bottom ones hold the marker and the stats). */
export interface IdentityCorners {
  topLeft: string[];   // the patient: name, ID
  topRight: string[];  // the study (date, description) and the series' description
}

/** "Doe^John^^Dr" -> "Doe, John Dr": family name, then the rest; of "alphabetic=ideographic=phonetic" the first. */
export function personName(dicomName: string): string {
  const parts = dicomName.split("=")[0].split("^").map((p) => p.trim()).filter((p) => p !== "");
  return parts.length < 2 ? parts.join("") : `${parts[0]}, ${parts.slice(1).join(" ")}`;
}

/** "20091203" -> "2009-12-03"; anything else as it is. */
export function studyDate(dicomDate: string): string {
  return /^\d{8}$/.test(dicomDate) ? `${dicomDate.slice(0, 4)}-${dicomDate.slice(4, 6)}-${dicomDate.slice(6)}` : dicomDate;
}

export function identityCorners(id: PatientIdentity): IdentityCorners {
  const lines = (...texts: string[]) => texts.filter((t) => t !== "");
  return {
    topLeft: lines(personName(id.patientName), id.patientId ? `ID ${id.patientId}` : ""),
    topRight: lines(studyDate(id.studyDate), id.studyDescription, id.seriesDescription),
  };
}

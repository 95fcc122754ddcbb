// IHE Invoke Image Display (IID, RAD-106): the launch address an EHR or RIS opens to show a patient's or a study's
// images, a contract other systems build (docs/web.md, "Launching from an EHR"):
//   /IHEInvokeImageDisplay?requestType=STUDY&studyUID=UID[,UID...]   (or accessionNumber=A[,A...])
//   /IHEInvokeImageDisplay?requestType=PATIENT&patientID=ID^^^&OID&ISO[&mostRecentResults=N]
// and the same under /iid. Optional: viewerType=IHE_BIR, diagnosticQuality=true|false, keyImagesOnly=true|false,
// and cinevol's own pacs=NAME (which of the server's PACS; default its first). The gateway refuses a malformed
// request with 400 and the reason; the page opens what a valid one names.

export const IID_PATHS = ["/iid", "/IHEInvokeImageDisplay"];

export interface IidRequest {
  requestType: "STUDY" | "PATIENT";
  studyUids: string[];     // STUDY: the studies, the first one opened
  accessionNumbers: string[];
  patientId: string;       // PATIENT: the CX value's ID (before its first ^)
  issuer: string;          // and its assigning authority as given (not matched: the PACS's search has no issuer)
  pacs?: string;
}

const UID = /^[0-9]+(\.[0-9]+)*$/;
const MAX_LIST = 16;  // studies one launch may name

function list(value: string | null): string[] {
  return (value ?? "").split(",").map((v) => v.trim()).filter((v) => v !== "");
}

/** The IID request `query` makes, or the reason it is refused (as 400 says it). */
export function readIid(query: URLSearchParams): IidRequest | string {
  const requestType = query.get("requestType");
  if (requestType !== "STUDY" && requestType !== "PATIENT") {
    return `requestType: '${requestType ?? ""}' is not STUDY or PATIENT`;
  }
  const viewerType = query.get("viewerType");
  if (viewerType !== null && viewerType !== "IHE_BIR") return `viewerType: '${viewerType}' is not supported (IHE_BIR is)`;
  for (const flag of ["diagnosticQuality", "keyImagesOnly"]) {
    const value = query.get(flag);
    if (value !== null && value !== "true" && value !== "false") return `${flag}: '${value}' is not true or false`;
  }
  const recent = query.get("mostRecentResults");
  if (recent !== null && !/^[1-9][0-9]{0,3}$/.test(recent)) return `mostRecentResults: '${recent}' is not a count`;
  const pacs = query.get("pacs") ?? undefined;
  if (pacs !== undefined && !/^[A-Za-z0-9_.-]{1,64}$/.test(pacs)) return `pacs: '${pacs}' is not a PACS name`;
  const request: IidRequest = { requestType, studyUids: [], accessionNumbers: [], patientId: "", issuer: "", pacs };
  if (requestType === "STUDY") {
    request.studyUids = list(query.get("studyUID"));
    request.accessionNumbers = list(query.get("accessionNumber"));
    if (request.studyUids.length + request.accessionNumbers.length === 0) {
      return "requestType STUDY: give studyUID or accessionNumber";
    }
    const bad = request.studyUids.find((uid) => uid.length > 64 || !UID.test(uid));
    if (bad !== undefined) return `studyUID: '${bad}' is not a UID`;
    const long = request.accessionNumbers.find((a) => a.length > 16);
    if (long !== undefined) return `accessionNumber: '${long}' is longer than 16 characters`;
    if (request.studyUids.length + request.accessionNumbers.length > MAX_LIST) {
      return `studyUID, accessionNumber: at most ${MAX_LIST} studies`;
    }
    return request;
  }
  const cx = query.get("patientID") ?? "";
  const [id, , , issuer] = cx.split("^");
  if (!id || id.length > 64) return "requestType PATIENT: give patientID (ID^^^&OID&ISO), its ID 1 to 64 characters";
  request.patientId = id;
  request.issuer = issuer ?? "";
  return request;
}

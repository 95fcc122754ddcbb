// A real Orthanc (Debian's, with its DICOMweb plugin) for the page's PACS test,
// as tests/pacs/orthanc_process.h starts it: its configuration and storage in
// a scratch folder, HTTP on a free port of 127.0.0.1 only (the loopback_bind
// preload), no DICOM port, remote access refused, a user made up per run;
// stopped by its pid, and killed by the kernel should the test die first
// (setpriv --pdeathsig). Also: the shared CT stamped with the UIDs and
// patient a PACS needs (DCMTK's dcmodify), and uploaded.
import { execFileSync, spawn } from "node:child_process";
import { randomBytes } from "node:crypto";
import { existsSync, mkdirSync, readdirSync, readFileSync, writeFileSync } from "node:fs";
import { createServer } from "node:net";
import { join } from "node:path";
import type { Running } from "./processes.js";

const PROGRAM = "/usr/sbin/Orthanc";
const DICOMWEB_PLUGIN = "/usr/share/orthanc/plugins/libOrthancDicomWeb.so";
const USER = "cinevol-test";
const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

export interface Orthanc extends Running {
  root: string;  // http://127.0.0.1:PORT, its own REST API
  password: string;
}

/** Empty when Orthanc, its DICOMweb plugin, the loopback preload and dcmodify are there; else what is missing. */
export function whatIsMissing(loopbackBind: string | undefined): string {
  if (!existsSync(PROGRAM)) return "Orthanc is not installed (scripts/install-deps.sh installs it)";
  if (!existsSync(DICOMWEB_PLUGIN)) return "Orthanc's DICOMweb plugin is not installed (install-deps.sh: orthanc-dicomweb)";
  if (!loopbackBind || !existsSync(loopbackBind)) return `the loopback preload was not built ('${loopbackBind ?? ""}')`;
  if (!existsSync("/usr/bin/dcmodify")) return "DCMTK's dcmodify is not installed (install-deps.sh: dcmtk)";
  return "";
}

/** The DICOMweb address cinevol-server is given, and the credentials file line that opens it. */
export const dicomWeb = (o: Orthanc) => `${o.root}/dicom-web`;
export const credentialsLine = (name: string, o: Orthanc) => `${name} basic ${USER}:${o.password}\n`;

/** Starts Orthanc with its files under `folder`; a free port may be taken before Orthanc binds it, so 3 tries. */
export async function startOrthanc(folder: string, loopbackBind: string): Promise<Orthanc> {
  const password = `pw-${randomBytes(12).toString("hex")}`;
  let log = "";
  for (let attempt = 0; attempt < 3; ++attempt) {
    const port = await freePort();
    writeConfiguration(folder, port, password);
    const orthanc = launch(folder, port, password, loopbackBind);
    if (await answersSystem(orthanc, 30)) return orthanc;
    log = orthanc.log();
    await stopOrthanc(orthanc);
  }
  throw new Error(`Orthanc did not start: ${log}`);
}

/** SIGTERM by pid, SIGKILL when it has not gone in 10 s. */
export async function stopOrthanc(orthanc: Orthanc | undefined): Promise<void> {
  const child = orthanc?.process;
  if (!child?.pid || child.exitCode !== null || child.signalCode !== null) return;
  const exited = new Promise((r) => child.once("exit", r));
  process.kill(child.pid, "SIGTERM");
  if (await Promise.race([exited.then(() => true), sleep(10_000).then(() => false)])) return;
  process.kill(child.pid, "SIGKILL");
  await exited;
}

/** Copies of the shared CT's files in `to`, stamped with a study, a series and a patient (the shared CT has none). */
export function stampCt(from: string, to: string, stamp: { studyUid: string; seriesUid: string; patientId: string;
                                                           patientName: string }): string[] {
  mkdirSync(to, { recursive: true });
  const files = readdirSync(from).filter((f) => f !== "README.txt").sort().map((f) => {
    writeFileSync(join(to, f), readFileSync(join(from, f)));
    return join(to, f);
  });
  // -gin: a new SOP Instance UID per file; the file meta header follows the data set's UIDs.
  execFileSync("/usr/bin/dcmodify", ["-nb", "-gin", "-m", "(0008,0016)=1.2.840.10008.5.1.4.1.1.2",
    "-m", `(0020,000d)=${stamp.studyUid}`, "-m", `(0020,000e)=${stamp.seriesUid}`,
    "-m", `(0010,0020)=${stamp.patientId}`, "-m", `(0010,0010)=${stamp.patientName}`, ...files], { stdio: "pipe" });
  return files;
}

/** Stores DICOM files through Orthanc's own REST API (POST /instances), one at a time. */
export async function upload(orthanc: Orthanc, files: string[]): Promise<void> {
  for (const file of files) {
    const answer = await fetch(`${orthanc.root}/instances`, {
      method: "POST", headers: { ...authorization(orthanc), "Content-Type": "application/dicom" },
      body: readFileSync(file), signal: AbortSignal.timeout(10_000),
    });
    if (answer.status !== 200) throw new Error(`Orthanc refused ${file}: ${answer.status} ${await answer.text()}`);
  }
}

/** The Authorization header that opens Orthanc's REST and DICOMweb APIs. */
export function authorization(orthanc: Orthanc): Record<string, string> {
  return { Authorization: `Basic ${Buffer.from(`${USER}:${orthanc.password}`).toString("base64")}` };
}

async function freePort(): Promise<number> {
  const server = createServer();
  await new Promise<void>((r) => server.listen(0, "127.0.0.1", r));
  const { port } = server.address() as { port: number };
  await new Promise((r) => server.close(r));
  return port;
}

function writeConfiguration(folder: string, port: number, password: string): void {
  const storage = join(folder, "storage");
  writeFileSync(join(folder, "orthanc.json"), JSON.stringify({
    Name: "cinevol-test", StorageDirectory: storage, IndexDirectory: storage, HttpPort: port,
    HttpServerEnabled: true, DicomServerEnabled: false, RemoteAccessAllowed: false,
    AuthenticationEnabled: true, RegisteredUsers: { [USER]: password }, HttpCompressionEnabled: false,
    ExecuteLuaEnabled: false, SaveJobs: false, Plugins: [DICOMWEB_PLUGIN],
    DicomWeb: { Enable: true, Root: "/dicom-web/", EnableWado: false },
  }, null, 2));
}

function launch(folder: string, port: number, password: string, loopbackBind: string): Orthanc {
  // Orthanc 1.10 binds every interface: the preload turns its wildcard bind into a loopback one.
  const env = { ...process.env, LD_PRELOAD: loopbackBind };
  // setpriv execs Orthanc in its own place: the pid is Orthanc's, and the kernel kills it should this process die.
  const child = spawn("/usr/bin/setpriv", ["--pdeathsig", "KILL", PROGRAM, join(folder, "orthanc.json")],
                      { env, stdio: ["ignore", "pipe", "pipe"] });
  let output = "";
  child.stdout!.on("data", (d) => { output += d; });
  child.stderr!.on("data", (d) => { output += d; });
  return { process: child, port, log: () => output, root: `http://127.0.0.1:${port}`, password };
}

/** Polls GET /system (with the credentials) until it answers 200, Orthanc dies or `seconds` pass. */
async function answersSystem(orthanc: Orthanc, seconds: number): Promise<boolean> {
  for (const end = Date.now() + seconds * 1000; Date.now() < end; await sleep(100)) {
    if (orthanc.process.exitCode !== null || orthanc.process.signalCode !== null) return false;
    try {
      const answer = await fetch(`${orthanc.root}/system`, { headers: authorization(orthanc),
                                                             signal: AbortSignal.timeout(2000) });
      if (answer.status === 200) return true;
    } catch {
      // not listening yet
    }
  }
  return false;
}

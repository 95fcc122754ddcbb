// The real programs an end-to-end test runs: cinevol-server and cinevol-web
// on free loopback ports, each stopped by its process id.
import { spawn, type ChildProcess } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

// Every file a test makes goes here; removed when the test process exits.
export const scratch = mkdtempSync(join(tmpdir(), "cinevol-web-e2e-"));
process.on("exit", () => rmSync(scratch, { recursive: true, force: true }));
const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

export interface Running {
  process: ChildProcess;
  port: number;
  log: () => string;
}

/** Starts a program that writes its port to --port-file; waits (bounded) for the port. */
export async function startWithPortFile(program: string, args: string[], name: string, seconds = 60): Promise<Running> {
  const portFile = join(scratch, `${name}-${Date.now()}.port`);
  let output = "";
  const child = spawn(program, [...args, "--port-file", portFile], { stdio: ["ignore", "pipe", "pipe"] });
  child.stdout!.on("data", (d) => { output += d; });
  child.stderr!.on("data", (d) => { output += d; });
  for (let waited = 0; waited < seconds * 1000; waited += 50) {
    if (existsSync(portFile) && readFileSync(portFile, "utf8").trim()) {
      return { process: child, port: Number(readFileSync(portFile, "utf8").trim()), log: () => output };
    }
    if (child.exitCode !== null) break;
    await sleep(50);
  }
  child.kill("SIGKILL");
  throw new Error(`${name} did not start: ${output}`);
}

/** SIGTERM, then SIGKILL after `seconds`. */
export async function stop(running: Running | undefined, signal: NodeJS.Signals = "SIGTERM", seconds = 10): Promise<void> {
  const child = running?.process;
  if (!child || child.exitCode !== null || child.signalCode !== null) return;
  const exited = new Promise((r) => child.once("exit", r));
  child.kill(signal);
  if (await Promise.race([exited.then(() => true), sleep(seconds * 1000).then(() => false)])) return;
  child.kill("SIGKILL");
  await exited;
}

export function tokensFile(lines: string): string {
  const path = join(scratch, "tokens");
  writeFileSync(path, lines);
  return path;
}

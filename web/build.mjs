// Builds the page, the gateway, the benches' node clients and the tests into
// OUT (the CMake build's web/ folder): protoc-gen-es writes the messages and
// services into gen/, tsc checks the types, esbuild bundles. No network:
// `npm ci` came first (scripts/install-deps.sh).
//   node build.mjs --out DIR [--proto DIR]
import { execFileSync } from "node:child_process";
import { copyFileSync, mkdirSync, readdirSync, rmSync, symlinkSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";
import * as esbuild from "esbuild";

const here = dirname(fileURLToPath(import.meta.url));
const { values } = parseArgs({ options: { out: { type: "string" }, proto: { type: "string" } } });
if (!values.out) throw new Error("--out DIR is required");
const out = resolve(values.out);
const proto = resolve(values.proto ?? join(here, "..", "proto"));
const bin = (name) => join(here, "node_modules", ".bin", name);

function generate() {
  rmSync(join(here, "gen"), { recursive: true, force: true });
  mkdirSync(join(here, "gen"));
  execFileSync("protoc", [`--plugin=protoc-gen-es=${bin("protoc-gen-es")}`, `--es_out=${join(here, "gen")}`,
    "--es_opt=target=ts", `-I${proto}`, "cinevol/v1/scene.proto", "cinevol/v1/service.proto"], { stdio: "inherit" });
}

const tests = (folder) => readdirSync(join(here, folder)).filter((f) => f.endsWith(".test.ts"))
  .map((f) => join(here, folder, f));

async function bundle() {
  rmSync(join(out, "static"), { recursive: true, force: true });
  mkdirSync(join(out, "static"), { recursive: true });
  const common = { bundle: true, sourcemap: "linked", logLevel: "warning", target: "es2022" };
  await esbuild.build({
    ...common, platform: "browser", format: "esm", minify: true,
    entryPoints: { app: join(here, "src", "main.ts"), "frame-worker": join(here, "src", "frame_worker.ts") },
    outdir: join(out, "static"),
  });
  for (const f of ["index.html", "app.css"]) copyFileSync(join(here, "static", f), join(out, "static", f));
  // Node bundles: ES modules that may still require() node's own modules.
  const node = { ...common, platform: "node", format: "esm", target: "node18", outExtension: { ".js": ".mjs" },
    banner: { js: "import { createRequire } from 'node:module'; const require = createRequire(import.meta.url);" } };
  await esbuild.build({ ...node, entryPoints: { gateway: join(here, "gateway", "main.ts") }, outdir: out });
  // The benches' node clients (bench/web-latency-run.sh).
  await esbuild.build({ ...node, entryPoints: { "motion-to-photon": join(here, "bench", "motion_to_photon.ts") },
                        outdir: join(out, "bench") });
  // The unit tests read the golden cases from the checkout they were built from (CINEVOL_GOLDEN overrides).
  await esbuild.build({ ...node, entryPoints: tests("test"), outdir: join(out, "tests"),
                        define: { CINEVOL_SOURCE_DIR: JSON.stringify(resolve(here, "..")) } });
  await esbuild.build({ ...node, entryPoints: tests("e2e"), outdir: join(out, "e2e"), external: ["playwright-core"] });
  // The end-to-end tests find playwright-core from the build tree through this link.
  rmSync(join(out, "node_modules"), { force: true });
  symlinkSync(join(here, "node_modules"), join(out, "node_modules"));
}

generate();
execFileSync(bin("tsc"), ["--noEmit", "-p", here], { stdio: "inherit" });
await bundle();

#!/usr/bin/env node
// Validates Kubernetes objects against the Kubernetes OpenAPI schemas, as the
// npm package kubernetes-models compiles them (pinned in package-lock.json here).
//
//   node validate.js --modules DIR [--label NAME] [FILE | -]
//
// DIR holds the node_modules that `npm ci` made from this folder's lock file
// (tests/deploy/check_manifests.py installs it outside the source tree). FILE
// (or stdin) is a JSON array of objects, e.g. `kubectl kustomize` rendered and
// parsed. Prints one line per problem, "NAME: Kind/name: /json/path message",
// and exits 1 when there is any, 2 when it cannot run, 0 when all are valid.
// An apiVersion/kind the package does not know (a custom resource, a typo) is
// a problem too: nothing goes unvalidated silently.
//
// The schemas check types, required fields, enums and formats (int32, int64,
// quantity, byte, ...) but not unknown fields: kubernetes-models' schemas carry
// no additionalProperties, so a misspelt field passes (kubectl --validate=strict
// against a cluster would catch it; this offline check does not).
"use strict";

const fs = require("fs");
const path = require("path");
const { pathToFileURL } = require("url");

function die(message) {
  process.stderr.write(`validate.js: ${message}\n` +
    "usage: node validate.js --modules DIR [--label NAME] [FILE | -]\n");
  process.exit(2);
}

function parseArgs(argv) {
  const args = { modules: process.env.CINEVOL_SCHEMA_MODULES, label: "input", input: "-" };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === "--modules" || a === "--label") {
      if (i + 1 >= argv.length) die(`${a} needs a value`);
      args[a.slice(2)] = argv[++i];
    } else if (a.startsWith("--") && a !== "--") {
      die(`unknown option ${a}`);
    } else {
      args.input = a;
    }
  }
  if (!args.modules) die("--modules DIR (or CINEVOL_SCHEMA_MODULES) is required");
  return args;
}

// One line per schema error. A oneOf/anyOf (Quantity, IntOrString) reports each
// branch's failure at the same path as well; fold those into one line.
function describeErrors(errors) {
  const describe = (e) => {
    let text = e.message || e.keyword;
    if (e.keyword === "enum" && e.params && e.params.allowedValues) {
      text += ` (${e.params.allowedValues.map((v) => JSON.stringify(v)).join(", ")})`;
    }
    return text;
  };
  const isBranch = (e) => e.keyword === "oneOf" || e.keyword === "anyOf";
  const branchPaths = new Set(errors.filter(isBranch).map((e) => e.instancePath));
  const lines = errors.map((e) => {
    const p = e.instancePath;
    if (!branchPaths.has(p)) return `${p || "/"} ${describe(e)}`;
    const alternatives = errors.filter((b) => b.instancePath === p && !isBranch(b)).map(describe);
    return `${p || "/"} fits none of its allowed forms: ${alternatives.join(" | ") || "no detail"}`;
  });
  return [...new Set(lines)];
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const pkgRoot = path.join(path.resolve(args.modules), "node_modules", "kubernetes-models");
  let pkgVersion;
  try {
    pkgVersion = JSON.parse(fs.readFileSync(path.join(pkgRoot, "package.json"), "utf8")).version;
  } catch (e) {
    die(`kubernetes-models is not installed under ${args.modules} (run npm ci there): ${e.message}`);
  }

  let objects;
  try {
    objects = JSON.parse(fs.readFileSync(args.input === "-" ? 0 : args.input, "utf8"));
  } catch (e) {
    die(`cannot read a JSON array from ${args.input === "-" ? "stdin" : args.input}: ${e.message}`);
  }
  if (!Array.isArray(objects)) die("the input is not a JSON array of objects");

  // The package mirrors apiVersion in its layout: v1/ConfigMap.js (core),
  // apps/v1/StatefulSet.js, networking.k8s.io/v1/Ingress.js. Its exports map
  // offers these only to import(), so they are imported by file URL from DIR.
  const models = new Map();
  async function modelFor(apiVersion, kind) {
    const key = `${apiVersion} ${kind}`;
    if (models.has(key)) return models.get(key);
    let found;
    if (typeof apiVersion !== "string" || typeof kind !== "string") {
      found = { unknown: "has no apiVersion or kind" };
    } else if (!/^([a-z0-9][a-z0-9.-]*\/)?v[0-9][a-z0-9]*$/.test(apiVersion) || !/^[A-Z][A-Za-z0-9]*$/.test(kind)) {
      found = { unknown: `apiVersion "${apiVersion}" / kind "${kind}" is malformed` };
    } else {
      const dir = path.join(pkgRoot, ...apiVersion.split("/"));
      const file = path.join(dir, `${kind}.js`);
      if (!fs.existsSync(dir)) {
        found = { unknown: `apiVersion ${apiVersion} is not a built-in Kubernetes API known to kubernetes-models ` +
                           `${pkgVersion} (a custom resource? CRDs cannot be validated here)` };
      } else if (!fs.existsSync(file)) {
        found = { unknown: `kind ${kind} is not in ${apiVersion} (kubernetes-models ${pkgVersion})` };
      } else {
        const cls = (await import(pathToFileURL(file).href))[kind];
        found = cls && cls.apiVersion === apiVersion && cls.kind === kind
          ? { cls }
          : { unknown: `${kind} is not a top-level object of ${apiVersion} (kubernetes-models ${pkgVersion})` };
      }
    }
    models.set(key, found);
    return found;
  }

  const problems = [];
  for (const [i, obj] of objects.entries()) {
    const ok = obj && typeof obj === "object" && !Array.isArray(obj);
    const kind = ok ? obj.kind : undefined;
    const name = (ok && obj.metadata && obj.metadata.name) || `#${i}`;
    const where = `${args.label}: ${kind || "?"}/${name}`;
    if (!ok) {
      problems.push(`${where}: not an object`);
      continue;
    }
    const { cls, unknown } = await modelFor(obj.apiVersion, kind);
    if (unknown) {
      problems.push(`${where}: ${unknown}`);
      continue;
    }
    try {
      new cls(obj).validate();
    } catch (e) {
      if (Array.isArray(e.errors)) {
        for (const line of describeErrors(e.errors)) problems.push(`${where}: ${line}`);
      } else {
        problems.push(`${where}: validation threw: ${e && e.message}`);
      }
    }
  }
  for (const p of problems) process.stdout.write(`${p}\n`);
  return problems.length ? 1 : 0;
}

main().then((code) => { process.exitCode = code; }, (e) => {
  process.stderr.write(`validate.js: ${e && e.stack ? e.stack : e}\n`);
  process.exitCode = 2;
});

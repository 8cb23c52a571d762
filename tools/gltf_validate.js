#!/usr/bin/env node
// Validate a glTF/GLB file with the Khronos glTF-Validator (npm `gltf-validator`, pinned in
// tools/package.json and tools/package-lock.json, installed by `npm ci` in tools/) and print its
// report as JSON on stdout.
//
//   node tools/gltf_validate.js FILE.glb
//
// Exit code: 0 no errors, 1 the asset has errors, 2 the validator could not run (missing
// package, unreadable file, not glTF).
"use strict";
const fs = require("fs");
const path = require("path");

let validator;
try {
  validator = require("gltf-validator");
} catch (err) {
  console.error("gltf_validate: the npm package 'gltf-validator' is not installed; run `npm ci` " +
                "in " + __dirname);
  process.exit(2);
}

const file = process.argv[2];
if (!file) {
  console.error("usage: node tools/gltf_validate.js FILE.glb");
  process.exit(2);
}
let data;
try {
  data = fs.readFileSync(file);
} catch (err) {
  console.error("gltf_validate: " + err.message);
  process.exit(2);
}
validator.validateBytes(new Uint8Array(data), {
  uri: path.basename(file),
  maxIssues: 0,  // unlimited
  writeTimestamp: false,
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)),
                (err, buf) => (err ? reject(err.toString()) : resolve(buf)));
  }),
}).then((report) => {
  report.validatorVersion = validator.version();
  process.stdout.write(JSON.stringify(report) + "\n");
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
}, (err) => {
  console.error("gltf_validate: " + err);
  process.exit(2);
});

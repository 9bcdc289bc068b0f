// Validate a glTF / glb with the Khronos glTF validator (npm "gltf-validator") and print its JSON report.
// Usage: NODE_PATH=<dir>/node_modules node gltf_validate.js FILE.glb
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
if (!file) {
  console.error("usage: node gltf_validate.js FILE.glb");
  process.exit(2);
}
const bytes = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // report every issue
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri} not expected`)),
  })
  .then((report) => {
    process.stdout.write(JSON.stringify(report, null, 1));
  })
  .catch((error) => {
    console.error(String(error));
    process.exit(1);
  });

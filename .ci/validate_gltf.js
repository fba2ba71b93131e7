// Validate one glTF / GLB file with the Khronos glTF-Validator (npm gltf-validator);
// print its report as JSON on stdout. Usage: node .ci/validate_gltf.js FILE
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require(path.join(__dirname, "node", "node_modules", "gltf-validator"));

const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(data, { uri: path.basename(file), maxIssues: 100, format: file.endsWith(".glb") ? "glb" : "gltf" })
  .then((report) => {
    process.stdout.write(JSON.stringify(report));
  })
  .catch((err) => {
    process.stderr.write(String(err) + "\n");
    process.exit(2);
  });

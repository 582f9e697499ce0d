// Validate a .glb/.gltf with the Khronos glTF-Validator (npm package gltf-validator).
// Usage: node tools/validate_gltf.js FILE  -> prints the report's issue summary as JSON; exit 1 on errors.
const fs = require("fs");
const path = require("path");
const validator = require(process.env.GLTF_VALIDATOR_MODULE || "gltf-validator");
const file = process.argv[2];
validator
  .validateBytes(new Uint8Array(fs.readFileSync(file)), { uri: path.basename(file), maxIssues: 50 })
  .then((report) => {
    console.log(JSON.stringify({ issues: report.issues, info: report.info }, null, 1));
    process.exit(report.issues.numErrors > 0 ? 1 : 0);
  })
  .catch((e) => {
    console.error(String(e));
    process.exit(2);
  });

// Validate glTF/GLB files with the Khronos glTF validator (npm package gltf-validator).
// Usage: node tools/gltf_validate.js FILE... ; prints one JSON report summary per file and exits
// 1 when any file has errors. `make install` puts the package in .venv/node (NODE_PATH).
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

async function main(files) {
  let failed = false;
  for (const file of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: path.basename(file),
      maxIssues: 100,
    });
    const issues = report.issues;
    console.log(JSON.stringify({
      file,
      validatorVersion: report.validatorVersion,
      errors: issues.numErrors,
      warnings: issues.numWarnings,
      infos: issues.numInfos,
      messages: issues.messages.filter((m) => m.severity <= 1).slice(0, 5).map((m) => `${m.code} ${m.pointer || ""}: ${m.message}`),
    }));
    failed = failed || issues.numErrors > 0;
  }
  process.exit(failed ? 1 : 0);
}

main(process.argv.slice(2)).catch((err) => { console.error(String(err)); process.exit(2); });

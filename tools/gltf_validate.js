// Validate glTF/GLB files with the Khronos glTF validator; print one JSON report per file.
// Usage: node tools/gltf_validate.js FILE...   (run `npm ci --prefix tools` first)
'use strict';
const fs = require('fs');
const validator = require('gltf-validator');

async function main(paths) {
  const reports = [];
  for (const path of paths) {
    const bytes = new Uint8Array(fs.readFileSync(path));
    const report = await validator.validateBytes(bytes, { uri: path, maxIssues: 100 });
    reports.push(report);
  }
  process.stdout.write(JSON.stringify(reports));
}

main(process.argv.slice(2)).catch((error) => {
  process.stderr.write(String(error) + '\n');
  process.exit(2);
});

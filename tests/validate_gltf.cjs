// Validates glTF/GLB files with the Khronos glTF validator (npm package
// `gltf-validator`, which has no command-line entry point).
//
//   npm install --prefix DIR gltf-validator@2.0.0-dev.3.10
//   NODE_PATH=DIR/node_modules node tests/validate_gltf.cjs out/*.glb
//
// Prints one line per file and every message; exits 1 if any file has an
// error (or cannot be read), 0 otherwise. `make validate-gltf` runs it on
// every example.
'use strict';
const fs = require('fs');
const validator = require('gltf-validator');

async function main(files) {
  if (files.length === 0) {
    console.error('usage: node tests/validate_gltf.cjs FILE.glb...');
    return 2;
  }
  let failed = 0;
  for (const file of files) {
    try {
      const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)));
      const { numErrors, numWarnings, numInfos } = report.issues;
      console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
      for (const m of report.issues.messages) {
        console.log(`  ${m.severity === 0 ? 'error' : 'note'} ${m.code}: ${m.message} ${m.pointer || ''}`);
      }
      if (numErrors > 0) failed++;
    } catch (err) {
      console.log(`${file}: cannot validate: ${err.message || err}`);
      failed++;
    }
  }
  console.log(`gltf-validator: ${files.length - failed} passed, ${failed} failed`);
  return failed > 0 ? 1 : 0;
}

main(process.argv.slice(2)).then((code) => process.exit(code));

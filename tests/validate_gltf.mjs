// Validates glTF 2.0 files (.gltf / .glb) with the Khronos glTF-Validator npm package.
//
// The package has no CLI entry point, so this script calls its `validateBytes` API. It loads
// `gltf-validator` through a CommonJS require rooted at the CURRENT WORKING DIRECTORY, so the
// module is found in `./node_modules` (or any parent's), or in a directory listed in NODE_PATH.
//
// Install once (any directory, e.g. a cache dir outside the repo):
//   npm install --prefix "$DIR" gltf-validator@2.0.0-dev.3.10
// Run from the repository root with NODE_PATH pointing at that install:
//   NODE_PATH="$DIR/node_modules" node tests/validate_gltf.mjs out/a.glb out/b.gltf
// or from the install directory itself:
//   (cd "$DIR" && node /path/to/repo/tests/validate_gltf.mjs /abs/path/a.glb)
//
// Options: --strict  also fail on warnings (default: fail only on errors).
// Prints one summary line per file (errors, warnings, infos, hints) and every error/warning.
// Exit status: 0 if every file passed, 1 if any failed validation, 2 on usage or setup errors.

import { createRequire } from 'node:module';
import { readFile } from 'node:fs/promises';
import path from 'node:path';

const args = process.argv.slice(2);
const strict = args.includes('--strict');
const files = args.filter((a) => a !== '--strict');
if (files.length === 0) {
  console.error('usage: node tests/validate_gltf.mjs [--strict] FILE.glb|FILE.gltf...');
  process.exit(2);
}

let validator;
try {
  const require = createRequire(path.join(process.cwd(), 'validate_gltf.cjs'));
  validator = require('gltf-validator');
} catch (e) {
  console.error(
    'cannot load gltf-validator: run `npm install --prefix DIR gltf-validator@2.0.0-dev.3.10` ' +
      'and set NODE_PATH=DIR/node_modules (or run from DIR)\n' + e.message,
  );
  process.exit(2);
}

let failed = false;
for (const file of files) {
  let report;
  try {
    const bytes = new Uint8Array(await readFile(file));
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 100,
      // External buffers and images are read relative to the file being validated.
      externalResourceFunction: (uri) =>
        readFile(path.join(path.dirname(file), decodeURIComponent(uri))).then(
          (data) => new Uint8Array(data),
        ),
    });
  } catch (e) {
    console.log(`${file}: validator failed: ${e && e.message ? e.message : e}`);
    failed = true;
    continue;
  }
  const i = report.issues;
  const bad = i.numErrors > 0 || (strict && i.numWarnings > 0);
  console.log(
    `${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ` +
      `${i.numHints} hints${bad ? '  FAILED' : ''}`,
  );
  for (const m of i.messages) {
    if (m.severity <= 1 || process.env.GLTF_VALIDATE_VERBOSE) {
      const kind = ['error', 'warning', 'info', 'hint'][m.severity] ?? `severity ${m.severity}`;
      console.log(`  ${kind} ${m.code} at ${m.pointer ?? '(file)'}: ${m.message}`);
    }
  }
  failed ||= bad;
}
process.exit(failed ? 1 : 0);

#!/usr/bin/env node
// Validates one glTF or GLB file with the Khronos glTF-Validator and prints its JSON report on
// stdout. Exit status: 0 when the validator ran (whatever it found: the caller reads the
// report's issues.numErrors and issues.numWarnings), 2 when it could not run (usage, unreadable
// file, format not detected).
//
// Usage: node tests/tools/validate_gltf.js FILE.glb
// The validator is installed by `npm ci --prefix tests/tools` (see .ci/run).
'use strict';

const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

const file = process.argv[2];
if (!file) {
  console.error('usage: validate_gltf.js FILE.glb');
  process.exit(2);
}
let bytes;
try {
  bytes = new Uint8Array(fs.readFileSync(file));
} catch (e) {
  console.error(`${file}: ${e.message}`);
  process.exit(2);
}
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    // Every issue counted, none cut off.
    maxIssues: 0,
    // A .glb from blockwalk refers to no external resource; any reference is reported.
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  })
  .then(
    (report) => {
      process.stdout.write(JSON.stringify(report, null, 2) + '\n');
    },
    (err) => {
      console.error(`${file}: the validator could not read it: ${err}`);
      process.exit(2);
    },
  );

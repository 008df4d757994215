// Runs the Khronos glTF validator (npm gltf-validator) on a .glb or .gltf: prints its issues and exits 1
// when it reports any error or warning. Used by tests/gltf_test.cpp on the daemon's exported files.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

const file = process.argv[2];
const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
  externalResourceFunction: () => Promise.reject(new Error('no external resources')),
});
const { numErrors, numWarnings, numInfos, messages } = report.issues;
for (const m of messages) console.log(`${['error', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer ?? ''}: ${m.message}`);
console.log(`gltf-validator ${report.validatorVersion}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
process.exit(numErrors + numWarnings > 0 ? 1 : 0);

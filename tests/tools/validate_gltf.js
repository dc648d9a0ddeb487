#!/usr/bin/env node
// Usage: node validate_gltf.js [--ignore=CODE1,CODE2] FILE.gltf|FILE.glb
// Validates with the Khronos glTF-Validator (npm gltf-validator), loading external
// resources (.bin buffers, images) relative to the asset's directory.
// Exit code: 0 = no errors and no warnings, 1 = errors or warnings, 2 = could not validate.
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

const args = process.argv.slice(2);
const ignored = args.filter(a => a.startsWith('--ignore=')).flatMap(a => a.slice(9).split(',')).filter(Boolean);
const file = args.find(a => !a.startsWith('--'));
if (!file) { console.error('usage: node validate_gltf.js [--ignore=CODE,...] FILE.gltf'); process.exit(2); }
const full = path.resolve(file);
let bytes;
try { bytes = fs.readFileSync(full); } catch (e) { console.error(String(e)); process.exit(2); }
const SEV = ['Error', 'Warning', 'Info', 'Hint'];

validator.validateBytes(new Uint8Array(bytes), {
  uri: path.basename(full),
  maxIssues: 0,              // unlimited
  writeTimestamp: false,
  ignoredIssues: ignored,     // e.g. MESH_PRIMITIVE_GENERATED_TANGENT_SPACE
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    const p = path.resolve(path.dirname(full), decodeURIComponent(uri));
    fs.readFile(p, (err, data) => err ? reject(err.toString()) : resolve(new Uint8Array(data)));
  }),
}).then((report) => {
  const is = report.issues;
  console.log(`glTF-Validator ${report.validatorVersion}: ${report.uri}`);
  console.log(`errors=${is.numErrors} warnings=${is.numWarnings} infos=${is.numInfos} hints=${is.numHints} truncated=${is.truncated}`);
  for (const m of is.messages) {
    console.log(`  [${SEV[m.severity] || m.severity}] ${m.code} ${m.pointer || (m.offset !== undefined ? '@' + m.offset : '')}: ${m.message}`);
  }
  if (report.info) {
    const i = report.info;
    console.log(`info: version=${i.version} generator=${i.generator || '-'} resources=${(i.resources || []).map(r => r.pointer + ':' + r.storage + (r.image ? `(${r.image.format} ${r.image.width}x${r.image.height} ${r.image.primaries}/${r.image.transfer})` : '')).join(', ')}`);
  }
  process.exit(is.numErrors > 0 || is.numWarnings > 0 ? 1 : 0);
}, (err) => { console.error('validation failed: ' + err); process.exit(2); });

#!/usr/bin/env node
// Usage: node validate_mtlx.js [--no-file-check] [--import] FILE.mtlx [FILE2.mtlx ...]
// Validates MaterialX documents with the real MaterialX core (C++ compiled to WASM, v1.39.4),
// taken from npm @needle-tools/materialx (bin/JsMaterialXGenShader.{js,wasm,data.txt}); the
// .data package holds the standard data libraries (stdlib, pbrlib, bxdf incl. standard_surface,
// open_pbr_surface, gltf_pbr, ...), loaded with mx.loadStandardLibraries().
// Checks: XML parse, Document.validate() (with its message), every node in the document resolves
// to a nodedef (core validate() does NOT flag unknown node categories), at least one material,
// and (unless --no-file-check) that every 'filename' input points to an existing file.
// Exit code: 0 valid, 1 invalid, 2 usage / internal error.
'use strict';
const fs = require('fs');
const path = require('path');

async function loadMaterialX() {
  const bin = path.join(path.dirname(require.resolve('@needle-tools/materialx/package.json')), 'bin');
  // The Emscripten glue is an ES module ("type":"module") whose node branch still calls
  // require("fs") and uses __dirname; provide both as globals before importing it.
  globalThis.require = require;
  globalThis.__dirname = bin;
  const { default: MaterialX } = await import(path.join(bin, 'JsMaterialXGenShader.js'));
  const mx = await MaterialX({
    // the package ships the Emscripten preload package renamed from .data to .data.txt
    locateFile: (p) => path.join(bin, p.endsWith('.data') ? p + '.txt' : p),
    print: () => {}, printErr: (s) => console.error('[materialx] ' + s),
  });
  const genContext = new mx.GenContext(mx.EsslShaderGenerator.create());
  const stdlib = mx.loadStandardLibraries(genContext); // reads /libraries/** from the WASM FS
  return { mx, stdlib };
}

function allNodes(doc) {
  const out = [...doc.getNodes()];
  for (const g of doc.getNodeGraphs()) out.push(...g.getNodes());
  return out;
}

async function validateFile(mx, stdlib, file, checkFiles, useImport) {
  const problems = [];
  const text = fs.readFileSync(file, 'utf8');
  const rootMatch = text.match(/<materialx\b[^>]*?\bversion\s*=\s*"([^"]*)"/);
  console.log(`${file}: declared version ${rootMatch ? rootMatch[1] : '(none)'}`);
  if (!/<materialx\b/.test(text)) problems.push('root element <materialx> not found');
  else if (!rootMatch) problems.push('<materialx> root has no version attribute');

  const doc = mx.createDocument();
  try {
    await mx.readFromXmlString(doc, text, path.dirname(path.resolve(file))); // upgrades to 1.39 on read
  } catch (e) {
    problems.push('read error: ' + (e && e.message ? e.message : String(e)));
    return problems;
  }
  const ownNodes = allNodes(doc); // collect before library import
  // setDataLibrary() references the libraries (fast); --import copies them into the document with
  // importLibrary() (~1.5 s extra per file). Both gave identical results on all test files.
  if (useImport) doc.importLibrary(stdlib); else doc.setDataLibrary(stdlib);

  const msg = {};
  const ok = doc.validate(msg);            // JS binding: validate(obj) sets obj.message on failure
  if (!ok) problems.push('Document.validate(): ' + String(msg.message || '').trim().replace(/\n/g, '\n    '));

  for (const n of ownNodes) {
    if (!n.getNodeDef()) problems.push(`no matching nodedef for node '${n.getNamePath()}' (category '${n.getCategory()}', type '${n.getType()}', inputs: ${n.getInputs().map(i => i.getName() + ':' + i.getType()).join(', ')})`);
  }
  const materials = ownNodes.filter(n => n.getType() === 'material');
  if (materials.length === 0) problems.push('no material node (e.g. <surfacematerial type="material">) in document');
  for (const m of materials) {
    const s = m.getInput('surfaceshader');
    const sn = s && s.getConnectedNode();
    console.log(`  material ${m.getName()} -> ${sn ? sn.getCategory() + ' ' + sn.getName() + ' (nodedef ' + (sn.getNodeDef() ? sn.getNodeDef().getName() : 'NONE') + ')' : 'NO SURFACESHADER'}`);
    if (!sn) problems.push(`material '${m.getName()}' has no connected surfaceshader`);
  }
  if (checkFiles) {
    const base = path.dirname(path.resolve(file));
    for (const n of ownNodes) for (const i of n.getInputs()) {
      if (i.getType() !== 'filename' || i.getConnectedNode()) continue;
      const rel = (i.getActiveFilePrefix() || '') + (i.getValueString() || '');
      if (!rel) { problems.push(`empty filename on ${i.getNamePath()}`); continue; }
      const p = path.resolve(base, rel);
      if (!fs.existsSync(p)) problems.push(`missing file for ${i.getNamePath()}: ${p}`);
    }
  }
  console.log(`  document version after read: ${doc.getVersionString()}, nodes: ${ownNodes.length}, validate(): ${ok}`);
  return problems;
}

(async () => {
  const args = process.argv.slice(2);
  const checkFiles = !args.includes('--no-file-check');
  const useImport = args.includes('--import');
  const files = args.filter(a => !a.startsWith('--'));
  if (files.length === 0) { console.error('usage: node validate_mtlx.js [--no-file-check] [--import] FILE.mtlx ...'); process.exit(2); }
  const { mx, stdlib } = await loadMaterialX();
  console.log(`MaterialX ${mx.getVersionString()} (WASM), stdlib nodedefs: ${stdlib.getNodeDefs().length}`);
  let failed = 0;
  for (const f of files) {
    const problems = await validateFile(mx, stdlib, f, checkFiles, useImport);
    if (problems.length) { failed++; console.log(`  INVALID (${problems.length}):\n` + problems.map(p => '  - ' + p).join('\n')); }
    else console.log('  VALID');
  }
  process.exit(failed ? 1 : 0);
})().catch((e) => { console.error('internal error: ' + (e && e.stack || e)); process.exit(2); });

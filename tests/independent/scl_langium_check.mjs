// Runs vscode-simatic-scl's Langium language server (parser, linker, validator) on SCL files
// without VS Code and prints every error as FILE:LINE:COLUMN: message (one a line).
// Usage: node scl_langium_check.mjs CHECKOUT FILE.scl...
//        node scl_langium_check.mjs CHECKOUT --list-builtins   (the names of its built-in library)
//   CHECKOUT: a built checkout of vscode-simatic-scl (`npm ci`, `npx langium generate`,
//   `npx tsc -b tsconfig.src.json`; docs/wiring-s7.md "Independent checks").
// Exit 0: no error; 1: errors printed; 2: bad usage or the checkout cannot be loaded.
// Its built-in TIA instructions are loaded as the VS Code extension loads them (builtin://);
// the files given are checked together (a block may call one defined in another file).
import path from 'node:path';
import fs from 'node:fs';
import { pathToFileURL } from 'node:url';

const [checkout, ...files] = process.argv.slice(2);
if (!checkout || files.length === 0) {
    console.error('usage: node scl_langium_check.mjs CHECKOUT FILE.scl...');
    process.exit(2);
}
const from = (rel) => pathToFileURL(path.join(path.resolve(checkout), rel)).href;
let langium, node, mod, builtins;
try {
    langium = await import(from('node_modules/langium/lib/index.js'));
    node = await import(from('node_modules/langium/lib/node/index.js'));
    mod = await import(from('out/language/scl-module.js'));
    builtins = await import(from('out/language/built-in-scl-libraries/built-ins.js'));
} catch (e) {
    console.error(`scl_langium_check: error: ${checkout} is not a built vscode-simatic-scl checkout: ${e.message}`);
    process.exit(2);
}
if (files.length === 1 && files[0] === '--list-builtins') {
    for (const text of Object.values(builtins.BuiltIns.uriMap)) {
        const m = /^\s*(?:FUNCTION_BLOCK|FUNCTION|TYPE)\s+"?(\w+)/im.exec(text);
        if (m) console.log(m[1]);
    }
    process.exit(0);
}
const { URI } = langium;
const services = mod.createSclServices({ ...node.NodeFileSystem });
const shared = services.shared;
const factory = shared.workspace.LangiumDocumentFactory;
const docs = shared.workspace.LangiumDocuments;
for (const key in builtins.BuiltIns.uriMap) {
    docs.addDocument(factory.fromString(builtins.BuiltIns.uriMap[key], URI.parse('builtin://' + key)));
}
const ours = [];
for (const f of files) {
    let text;
    try {
        text = fs.readFileSync(f, 'utf-8');
    } catch (e) {
        console.error(`scl_langium_check: error: ${f}: ${e.message}`);
        process.exit(2);
    }
    const doc = factory.fromString(text, URI.file(path.resolve(f)));
    docs.addDocument(doc);
    ours.push([f, doc]);
}
await shared.workspace.DocumentBuilder.build([...docs.all], { validation: true });
let errors = 0;
for (const [f, doc] of ours) {
    for (const d of doc.diagnostics ?? []) {
        if (d.severity !== 1) continue;     // 1 = error (LSP DiagnosticSeverity)
        errors += 1;
        // a parse error lists every token it expected: keep its first and last line
        const lines = d.message.split('\n');
        const msg = lines.length > 1 ? `${lines[0]} ... ${lines[lines.length - 1].trim()}` : lines[0];
        console.log(`${f}:${d.range.start.line + 1}:${d.range.start.character + 1}: ${msg}`);
    }
}
process.exit(errors ? 1 : 0);

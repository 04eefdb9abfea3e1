// Checks that a `pinsim share` page holds none of a plugin's source: no line of the given
// source files (trimmed, 16 characters or more) appears in the page's HTML or in the wasm
// binary embedded in its engine (base64, decoded here).
// Usage: node page_has_no_source.js PAGE SOURCE...
"use strict";
const fs = require("fs");

const [page, ...sources] = process.argv.slice(2);
const html = fs.readFileSync(page, "latin1");
// The data URI whose payload starts with the wasm magic "\0asm" (base64 "AGFzbQ"); the
// engine also holds the bare prefix as a string constant.
const marker = "data:application/octet-stream;base64,";
const at = html.indexOf(marker + "AGFzbQ");
if (at < 0) throw new Error(`${page}: no embedded wasm (${marker}AGFzbQ...) found`);
const end = html.slice(at + marker.length).search(/[^A-Za-z0-9+/=]/);
const wasm = Buffer.from(html.slice(at + marker.length, at + marker.length + end), "base64");
if (wasm.readUInt32LE(0) !== 0x6d736100) throw new Error("the embedded data is not a wasm binary");
const wasmText = wasm.toString("latin1");
let checked = 0;
for (const file of sources) {
  for (const raw of fs.readFileSync(file, "utf8").split("\n")) {
    const line = raw.trim();
    if (line.length < 16) continue;
    ++checked;
    if (html.includes(line)) throw new Error(`the page's HTML holds a line of ${file}: ${line}`);
    if (wasmText.includes(line)) throw new Error(`the page's wasm holds a line of ${file}: ${line}`);
  }
}
if (checked === 0) throw new Error("no source line was long enough to check");
console.log(`${checked} source lines checked: none in the page (${(html.length / 1024).toFixed(0)} kB, ` +
            `wasm ${(wasm.length / 1024).toFixed(0)} kB)`);

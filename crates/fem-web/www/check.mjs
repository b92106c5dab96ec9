// The WebAssembly side of the bit-identity check, under node: load the module, run a built-in
// case for a number of steps through the same exports the page uses, print the state's
// fingerprint. `cargo xtask web --check` compares it with the native build's.
//
//   node check.mjs fem_web.wasm case-a 500 [KEY=VALUE ...]
import { readFile } from "node:fs/promises";

const [wasmPath, kase = "case-a", steps = "500", ...sets] = process.argv.slice(2);
const { instance } = await WebAssembly.instantiate(await readFile(wasmPath), {
  env: { now_ms: () => performance.now() },
});
const x = instance.exports;
const enc = new TextEncoder();
const dec = new TextDecoder();
function input(s) {
  const bytes = enc.encode(s);
  const ptr = x.input(bytes.length);
  new Uint8Array(x.memory.buffer, ptr, bytes.length).set(bytes);
}
function text() {
  return dec.decode(new Uint8Array(x.memory.buffer, x.text(), x.text_len()));
}
input(kase);
if (x.load_case() !== 0) {
  console.error(`error: ${text()}`);
  process.exit(2);
}
for (const kv of sets) {
  const eq = kv.indexOf("=");
  const key = eq < 0 ? kv : kv.slice(0, eq);
  input(key + (eq < 0 ? "" : kv.slice(eq + 1)));
  if (x.set(new TextEncoder().encode(key).length) === 1) {
    console.error(`error: ${text()}`);
    process.exit(2);
  }
}
if (x.step(Number(steps)) < 0) {
  console.error(`error: ${text()}`);
  process.exit(1);
}
x.state_hash();
console.log(text());

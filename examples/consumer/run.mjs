// The report in WebAssembly, under node:
//   node run.mjs target/wasm32-unknown-unknown/release/fem2d_consumer.wasm
import { readFile } from "node:fs/promises";

const [wasmPath] = process.argv.slice(2);
const { instance } = await WebAssembly.instantiate(await readFile(wasmPath), {
  env: { now_ms: () => performance.now() },
});
const x = instance.exports;
const code = x.run();
const text = new TextDecoder().decode(new Uint8Array(x.memory.buffer, x.text(), x.text_len()));
if (code !== 0) {
  process.stderr.write(`error: ${text}\n`);
  process.exit(1);
}
process.stdout.write(text);

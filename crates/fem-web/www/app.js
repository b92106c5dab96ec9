// The page of the interactive app: loads the WebAssembly module (the project's own crates),
// draws the body on a canvas, turns pointer and touch input into grab / drag / release, and
// runs the real-time loop (see crates/fem-web/src/app.rs for the clock). No physics here.
//
// The page exposes `window.fem` (the exports, the frame counter and a few readers) so a
// browser test can drive it like a person and read its counters.

const $ = (id) => document.getElementById(id);
const enc = new TextEncoder();
const dec = new TextDecoder();

const { instance } = await WebAssembly.instantiate(
  await (await fetch("fem_web.wasm")).arrayBuffer(),
  {},
);
const x = instance.exports;

function input(s) {
  const bytes = typeof s === "string" ? enc.encode(s) : s;
  const ptr = x.input(bytes.length);
  new Uint8Array(x.memory.buffer, ptr, bytes.length).set(bytes);
  return bytes.length;
}
function text() {
  return dec.decode(new Uint8Array(x.memory.buffer, x.text(), x.text_len()).slice());
}
function f32(ptr) {
  return new Float32Array(x.memory.buffer, ptr, x.out_len()).slice();
}
function f64(ptr) {
  return new Float64Array(x.memory.buffer, ptr, x.out_len()).slice();
}
function u32(ptr) {
  return new Uint32Array(x.memory.buffer, ptr, x.out_len()).slice();
}

const fem = {
  exports: x,
  frames: 0,
  errors: [],
  hud: () => f64(x.hud()),
  positions: () => f32(x.positions()),
  field: (k) => f32(x.field(k)),
  names: () => (x.names(), text()),
  stateHash: () => (x.state_hash(), text()),
  set: (key, value) => setKey(key, value),
  view: null,
};
window.fem = fem;

function showError(message) {
  $("error").textContent = message || "";
  if (message) fem.errors.push(message);
}

// --- Controls -----------------------------------------------------------------------------

x.catalogue();
const [cases, energies, solvers] = text().split("\n").map((l) => l.split(" "));
for (const [id, names] of [["case", cases], ["energy", energies], ["solver", solvers]]) {
  for (const n of names) $(id).add(new Option(n, n));
}
const numeric = {
  dt: "solver.dt",
  substeps: "solver.substeps",
  iterations: "solver.iterations",
  youngs_modulus: "material.youngs_modulus",
  poisson_ratio: "material.poisson_ratio",
  damping: "solver.damping",
};

function get(key) {
  input(key);
  x.get();
  return text();
}

function syncControls() {
  $("energy").value = get("energy").replaceAll('"', "");
  $("solver").value = get("solver.kind").replaceAll('"', "");
  for (const [id, key] of Object.entries(numeric)) {
    const v = get(key);
    $(id).value = v === "" ? "" : Number(v);
    $(id).disabled = v === "";
  }
}

let triangles = new Uint32Array(0);
let bounds = [0, 0, 1, 1];
function loaded() {
  triangles = u32(x.triangles());
  bounds = f64(x.bounds());
  syncControls();
  showError("");
}

function loadCase(name) {
  input(name);
  if (x.load_case() !== 0) return showError(text());
  loaded();
}

function setKey(key, value) {
  const n = enc.encode(key).length;
  input(key + value);
  const r = x.set(n);
  if (r === 1) {
    showError(text());
    syncControls();
    return false;
  }
  if (r === 2) triangles = u32(x.triangles());
  bounds = f64(x.bounds());
  showError("");
  syncControls();
  return true;
}

$("case").onchange = (e) => loadCase(e.target.value);
$("energy").onchange = (e) => setKey("energy", `"${e.target.value}"`);
$("solver").onchange = (e) => setKey("solver.kind", `"${e.target.value}"`);
for (const [id, key] of Object.entries(numeric)) {
  $(id).onchange = (e) => setKey(key, String(Number(e.target.value)));
}
let paused = false;
$("pause").onclick = () => {
  paused = !paused;
  $("pause").textContent = paused ? "run" : "pause";
};
$("single").onclick = () => {
  paused = true;
  $("pause").textContent = "run";
  if (x.step(1) < 0) showError(text());
  x.end_frame(1, 0, 0);
};
$("reset").onclick = () => {
  x.reset();
  showError("");
};

async function loadFile(file) {
  const bytes = new Uint8Array(await file.arrayBuffer());
  if (file.name.endsWith(".json")) {
    // A mesh: keep it, and wrap it in a scene that names it.
    const n = input(file.name);
    const all = new Uint8Array(n + bytes.length);
    all.set(enc.encode(file.name));
    all.set(bytes, n);
    input(all);
    x.add_file(n);
    const scene =
      `name = "${file.name}"\ngravity = [0.0, -9.8]\n[mesh]\nkind = "file"\npath = "${file.name}"\n` +
      `[material]\nyoungs_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n` +
      `[solver]\nkind = "xpbd"\ndt = 0.01\nsteps = 1000\nsubsteps = 10\n`;
    return loadScene(file.name, enc.encode(scene));
  }
  return loadScene(file.name, bytes);
}
function loadScene(name, bytes) {
  const n = enc.encode(name).length;
  const all = new Uint8Array(n + bytes.length);
  all.set(enc.encode(name));
  all.set(bytes, n);
  input(all);
  if (x.load_scene(n) !== 0) return showError(text());
  loaded();
}
$("file").onchange = (e) => e.target.files[0] && loadFile(e.target.files[0]);
const view = $("view");
view.ondragover = (e) => {
  e.preventDefault();
  view.classList.add("dragover");
};
view.ondragleave = () => view.classList.remove("dragover");
view.ondrop = (e) => {
  e.preventDefault();
  view.classList.remove("dragover");
  if (e.dataTransfer.files[0]) loadFile(e.dataTransfer.files[0]);
};

// --- Drawing ------------------------------------------------------------------------------

const canvas = $("c");
const ctx = canvas.getContext("2d");
let camera = { scale: 1, ox: 0, oy: 0 };

function fitCamera() {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth * dpr;
  const h = canvas.clientHeight * dpr;
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
  // The rest mesh with room around it to drag into.
  const [x0, y0, x1, y1] = bounds;
  const pad = 0.6 * Math.max(x1 - x0, y1 - y0);
  const sx = w / (x1 - x0 + 2 * pad);
  const sy = h / (y1 - y0 + 2 * pad);
  const scale = Math.min(sx, sy);
  camera = {
    scale,
    ox: w / 2 - scale * (x0 + x1) / 2,
    oy: h / 2 + scale * (y0 + y1) / 2,
  };
  fem.view = { ...camera, dpr };
}
const toScreen = (px, py) => [camera.ox + camera.scale * px, camera.oy - camera.scale * py];
function toWorld(clientX, clientY) {
  const r = canvas.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  const sx = (clientX - r.left) * dpr;
  const sy = (clientY - r.top) * dpr;
  return [(sx - camera.ox) / camera.scale, (camera.oy - sy) / camera.scale];
}

// Blue - white - red for stress, a viridis-like ramp otherwise.
function colour(t, kind) {
  t = Math.min(1, Math.max(0, t));
  if (kind === 2) {
    // det F: red below 1 (compressed, inverted at 0), blue above.
    const a = Math.abs(t - 0.5) * 2;
    return t < 0.5
      ? `rgb(${255},${Math.round(255 * (1 - a))},${Math.round(255 * (1 - a))})`
      : `rgb(${Math.round(255 * (1 - a))},${Math.round(255 * (1 - a * 0.6))},255)`;
  }
  const r = Math.round(255 * Math.min(1, 0.1 + 1.6 * t));
  const g = Math.round(255 * Math.min(1, 0.2 + 1.2 * t * (1 - t) * 2.2));
  const b = Math.round(255 * Math.max(0, 0.55 - 0.6 * t));
  return `rgb(${r},${g},${b})`;
}

function drawColorbar(lo, hi, kind, unit) {
  const cb = $("cb").getContext("2d");
  for (let i = 0; i < 240; i++) {
    cb.fillStyle = colour(i / 239, kind);
    cb.fillRect(i, 0, 1, 14);
  }
  $("lo").textContent = lo.toPrecision(3);
  $("hi").textContent = hi.toPrecision(3);
  $("unit").textContent = unit;
}

let grabbing = false;
let hand = null;

function draw() {
  fitCamera();
  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  const kind = Number($("field").value);
  const pos = f32(x.positions());
  const values = f32(x.field(kind));
  const perVertex = kind === 1;
  let lo = Infinity;
  let hi = -Infinity;
  for (const v of values) {
    if (Number.isFinite(v)) {
      lo = Math.min(lo, v);
      hi = Math.max(hi, v);
    }
  }
  if (kind === 2) {
    lo = 0;
    hi = 2;
  } else {
    lo = 0;
    if (!(hi > 0)) hi = 1;
  }
  // Scenery: ground and obstacles.
  const sc = f64(x.scenery());
  ctx.strokeStyle = "#555";
  ctx.lineWidth = 2;
  if (sc[0] === 1) {
    const [px, py, nx, ny] = [sc[1], sc[2], sc[3], sc[4]];
    const big = 1e3;
    const a = toScreen(px - ny * big, py + nx * big);
    const b = toScreen(px + ny * big, py - nx * big);
    ctx.beginPath();
    ctx.moveTo(...a);
    ctx.lineTo(...b);
    ctx.stroke();
  }
  let k = 6;
  for (let o = 0; o < sc[5]; o++) {
    const n = sc[k++];
    ctx.beginPath();
    for (let i = 0; i < n; i++) {
      const p = toScreen(sc[k + 2 * i], sc[k + 2 * i + 1]);
      i === 0 ? ctx.moveTo(...p) : ctx.lineTo(...p);
    }
    k += 2 * n;
    ctx.closePath();
    ctx.fillStyle = "#999";
    ctx.fill();
    ctx.stroke();
  }
  // The body.
  ctx.lineWidth = 0.5;
  ctx.strokeStyle = "rgba(0,0,0,0.25)";
  for (let t = 0; t < triangles.length / 3; t++) {
    const a = triangles[3 * t];
    const b = triangles[3 * t + 1];
    const c = triangles[3 * t + 2];
    const v = perVertex ? (values[a] + values[b] + values[c]) / 3 : values[t];
    ctx.fillStyle = Number.isFinite(v) ? colour((v - lo) / (hi - lo), kind) : "#000";
    ctx.beginPath();
    ctx.moveTo(...toScreen(pos[2 * a], pos[2 * a + 1]));
    ctx.lineTo(...toScreen(pos[2 * b], pos[2 * b + 1]));
    ctx.lineTo(...toScreen(pos[2 * c], pos[2 * c + 1]));
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
  }
  if (grabbing && hand) {
    ctx.strokeStyle = "#06c";
    ctx.lineWidth = 2;
    const h = toScreen(...hand);
    ctx.beginPath();
    ctx.arc(h[0], h[1], 6, 0, 2 * Math.PI);
    ctx.stroke();
  }
  const units = ["Pa", "m", ""];
  drawColorbar(lo, hi, kind, units[kind]);
}

// --- Pointer: grab, drag, release (mouse and touch alike) ---------------------------------

canvas.addEventListener("pointerdown", (e) => {
  const [wx, wy] = toWorld(e.clientX, e.clientY);
  const stiffness = $("grab").value === "spring" ? Number($("stiffness").value) : 0;
  if (x.grab_at(wx, wy, stiffness) === 1) {
    grabbing = true;
    hand = [wx, wy];
    canvas.setPointerCapture(e.pointerId);
    canvas.style.cursor = "grabbing";
  }
});
canvas.addEventListener("pointermove", (e) => {
  if (!grabbing) return;
  hand = toWorld(e.clientX, e.clientY);
  x.drag_to(hand[0], hand[1]);
});
function letGo() {
  if (!grabbing) return;
  grabbing = false;
  hand = null;
  x.release();
  canvas.style.cursor = "grab";
}
canvas.addEventListener("pointerup", letGo);
canvas.addEventListener("pointercancel", letGo);

// --- The real-time loop --------------------------------------------------------------------

// Physics may use this much of a frame; the rest is drawing and the browser's own work.
const PHYSICS_BUDGET_MS = 12;
let last = null;
let fps = 0;
let drawMs = 0;
function frame(now) {
  const wall = last === null ? 1 / 60 : (now - last) / 1000;
  last = now;
  fps = fps === 0 ? 1 / wall : 0.9 * fps + 0.1 / wall;
  let physics = 0;
  if (!paused) {
    const want = x.begin_frame(wall);
    const t0 = performance.now();
    let done = 0;
    // Steps in chunks, so the budget is checked without a clock call per step.
    let chunk = 1;
    while (done < want && performance.now() - t0 < PHYSICS_BUDGET_MS) {
      const k = x.step(Math.min(chunk, want - done));
      if (k < 0) {
        showError(text());
        break;
      }
      done += k;
      chunk = Math.min(chunk * 2, 64);
    }
    physics = performance.now() - t0;
    x.end_frame(done, physics, wall);
  }
  const d0 = performance.now();
  draw();
  drawMs = 0.9 * drawMs + 0.1 * (performance.now() - d0);
  const h = f64(x.hud());
  if (h[15] === 1) showError(text());
  fem.frames += 1;
  const force = h[12] === 1 ? `${h[13].toFixed(3)}, ${h[14].toFixed(3)} N` : "-";
  $("hud").innerHTML =
    `${fem.names()}\n` +
    `t               ${h[0].toFixed(4)} s\n` +
    `steps           ${h[1]}\n` +
    `fps             ${fps.toFixed(1)}\n` +
    `steps/frame     ${h[2]} of ${h[3]}\n` +
    `physics         ${h[4].toFixed(2)} ms/frame\n` +
    `drawing         ${drawMs.toFixed(2)} ms/frame\n` +
    `real-time factor ${h[5].toFixed(3)}` +
    (h[6] === 1 ? `  <span id="slow">slowed</span>` : "") +
    `\n` +
    `peak von Mises  ${h[7].toPrecision(4)} Pa\n` +
    `inverted        ${h[8]}\n` +
    `min det F       ${h[9].toFixed(4)}\n` +
    `area error      ${(100 * h[10]).toFixed(3)} % (|dA| summed)\n` +
    `area change     ${(100 * h[11]).toFixed(3)} %\n` +
    `grab force      ${force}`;
  requestAnimationFrame(frame);
}

loadCase(new URLSearchParams(location.search).get("case") || "case-a");
$("case").value = new URLSearchParams(location.search).get("case") || "case-a";
window.addEventListener("error", (e) => fem.errors.push(String(e.message)));
requestAnimationFrame(frame);

// The page of the interactive app: loads the WebAssembly module (the project's own crates),
// draws the body on a canvas, turns pointer and touch input into grab / drag / release, and
// runs the real-time loop (see crates/fem-web/src/app.rs for the clock). No physics here.
//
// Side by side: each pane is its own instance of the module (its own memory, its own app)
// running the same scene under its own energy and solver; one hand drives them all (a grab in
// any pane grabs every pane at the same world point).
//
// The page exposes `window.fem` (pane 0's readers, every pane, the frame counter) so a browser
// test can drive it like a person and read its counters.

const $ = (id) => document.getElementById(id);
const enc = new TextEncoder();
const dec = new TextDecoder();

const module = await WebAssembly.compile(await (await fetch("fem_web.wasm")).arrayBuffer());

// What the module imports: the clock its timings read, in milliseconds.
const HOST = { env: { now_ms: () => performance.now() } };

// One instance of the module and the helpers to talk to it.
async function instance() {
  const x = (await WebAssembly.instantiate(module, HOST)).exports;
  const io = {
    x,
    input(s) {
      const bytes = typeof s === "string" ? enc.encode(s) : s;
      const ptr = x.input(bytes.length);
      new Uint8Array(x.memory.buffer, ptr, bytes.length).set(bytes);
      return bytes.length;
    },
    text: () => dec.decode(new Uint8Array(x.memory.buffer, x.text(), x.text_len()).slice()),
    f32: (ptr) => new Float32Array(x.memory.buffer, ptr, x.out_len()).slice(),
    f64: (ptr) => new Float64Array(x.memory.buffer, ptr, x.out_len()).slice(),
    u32: (ptr) => new Uint32Array(x.memory.buffer, ptr, x.out_len()).slice(),
    // name + bytes in one input; the name's length.
    named(name, bytes) {
      const n = enc.encode(name).length;
      const all = new Uint8Array(n + bytes.length);
      all.set(enc.encode(name));
      all.set(bytes, n);
      io.input(all);
      return n;
    },
    get(key) {
      io.input(key);
      x.get();
      return io.text();
    },
  };
  return io;
}

function showError(message) {
  $("error").textContent = message || "";
  if (message) fem.errors.push(message);
}

// --- Colours --------------------------------------------------------------------------------

// A dark-blue to yellow to red ramp for stress and displacement; red-white-blue around 1 for
// det F.
function colour(t, kind) {
  t = Math.min(1, Math.max(0, t));
  if (kind === 2) {
    const a = Math.abs(t - 0.5) * 2;
    return t < 0.5
      ? `rgb(255,${Math.round(255 * (1 - a))},${Math.round(255 * (1 - a))})`
      : `rgb(${Math.round(255 * (1 - a))},${Math.round(255 * (1 - a * 0.6))},255)`;
  }
  const r = Math.round(255 * Math.min(1, 0.1 + 1.6 * t));
  const g = Math.round(255 * Math.min(1, 0.2 + 1.2 * t * (1 - t) * 2.2));
  const b = Math.round(255 * Math.max(0, 0.55 - 0.6 * t));
  return `rgb(${r},${g},${b})`;
}

// The colours as 256 ready strings per field kind (no string formatting per triangle).
const palette = [0, 1, 2].map((kind) =>
  Array.from({ length: 256 }, (_, i) => colour((i + 0.5) / 256, kind)),
);

// The contact pressure's ramp (dark purple, red, orange, light yellow), apart from the fields'.
function pressureColour(t) {
  t = Math.min(1, Math.max(0, t));
  const r = Math.round(255 * Math.min(1, 0.25 + 1.5 * t));
  const g = Math.round(255 * Math.max(0, Math.min(1, 1.4 * t * t)));
  const b = Math.round(255 * (0.35 * (1 - t) + 0.55 * t * t * t));
  return `rgb(${r},${g},${b})`;
}

// Stiff material regions (bone) in the stress map: one flat colour, outside the colour range
// (their stress, a thousand times the soft tissue's, would leave the soft tissue one dark
// colour), outlined in red as in the report's Figure 5.
const FLAT_COLOUR = "#f4eedc";
const OUTLINE_COLOUR = "#d0202a";

// The edges to outline: between triangles of different material regions, and the boundary
// edges of triangles not of the base material (vertex pairs, flattened). The report's
// pictures compute the same edges in Rust (`fem_render::frame::region_edges`); the page has
// its own few lines because the module leaves the rasteriser crate out.
function regionOutline(tri, regions) {
  const seen = new Map();
  const out = [];
  const nv = tri.reduce((m, v) => Math.max(m, v), 0) + 1;
  for (let t = 0; t < tri.length / 3; t++) {
    for (let k = 0; k < 3; k++) {
      const a = tri[3 * t + k];
      const b = tri[3 * t + ((k + 1) % 3)];
      const key = Math.min(a, b) * nv + Math.max(a, b);
      const other = seen.get(key);
      if (other === undefined) seen.set(key, t);
      else {
        seen.delete(key);
        if (regions[other] !== regions[t]) out.push(a, b);
      }
    }
  }
  for (const [key, t] of seen) {
    if (regions[t] !== 0) out.push(Math.floor(key / nv), key % nv);
  }
  return Uint32Array.from(out);
}

// --- A pane ---------------------------------------------------------------------------------

class Pane {
  constructor(io, index) {
    this.io = io;
    this.index = index;
    this.triangles = new Uint32Array(0);
    this.boundary = new Uint32Array(0);
    this.regions = new Uint32Array(0);
    this.outline = new Uint32Array(0);
    this.hasRegions = false;
    this.flatLabel = "";
    this.bounds = [0, 0, 1, 1];
    this.camera = { scale: 1, ox: 0, oy: 0, dpr: 1 };
    this.drawMs = 0;
    const el = document.createElement("div");
    el.className = "pane";
    el.innerHTML =
      `<div class="panebar"><label>energy <select class="energy"></select></label>` +
      `<label>solver <select class="solver"></select></label>` +
      (index > 0 ? `<button class="remove">remove</button>` : "") +
      `</div><canvas class="view"></canvas><div class="hud"></div>`;
    $("panes").append(el);
    this.el = el;
    this.canvas = el.querySelector("canvas");
    this.ctx = this.canvas.getContext("2d");
    this.hudEl = el.querySelector(".hud");
    for (const n of energies) el.querySelector(".energy").add(new Option(n, n));
    for (const n of solvers) el.querySelector(".solver").add(new Option(n, n));
    el.querySelector(".energy").onchange = (e) => this.set("energy", `"${e.target.value}"`);
    el.querySelector(".solver").onchange = (e) => this.set("solver.kind", `"${e.target.value}"`);
    if (index > 0) el.querySelector(".remove").onclick = () => removePane(this);
    attachPointer(this);
  }

  loaded() {
    const { x, u32, f64 } = this.io;
    this.triangles = u32(x.triangles());
    this.boundary = u32(x.boundary_edges());
    this.bounds = f64(x.bounds());
    this.loadRegions();
    this.sync();
  }

  // The triangles' material regions (they change with `regions` and the mesh), their
  // outline and the flat colour's legend: the names of the regions other than the base.
  loadRegions() {
    const { x, u32, text } = this.io;
    this.regions = u32(x.material_regions());
    this.hasRegions = this.regions.some((r) => r !== 0);
    this.outline = this.hasRegions ? regionOutline(this.triangles, this.regions) : new Uint32Array(0);
    x.material_region_names();
    const all = text().split("\n");
    this.baseName = all[0];
    const names = all.slice(1);
    const used = new Set(this.regions);
    this.flatLabel = names.filter((_, i) => used.has(i + 1)).join(", ");
  }

  loadCase(name) {
    this.io.input(name);
    if (this.io.x.load_case() !== 0) return this.io.text();
    this.loaded();
    return null;
  }

  loadScene(name, bytes) {
    const n = this.io.named(name, bytes);
    if (this.io.x.load_scene(n) !== 0) return this.io.text();
    this.loaded();
    return null;
  }

  set(key, value) {
    const { x, input, text, u32, f64 } = this.io;
    const n = enc.encode(key).length;
    input(key + value);
    const r = x.set(n);
    if (r === 1) {
      showError(`pane ${this.index + 1}: ${text()}`);
      this.sync();
      return false;
    }
    if (r === 2) {
      this.triangles = u32(x.triangles());
      this.boundary = u32(x.boundary_edges());
    }
    this.bounds = f64(x.bounds());
    this.loadRegions();
    showError("");
    this.sync();
    return true;
  }

  sync() {
    const get = this.io.get;
    this.el.querySelector(".energy").value = get("energy").replaceAll('"', "");
    this.el.querySelector(".solver").value = get("solver.kind").replaceAll('"', "");
    if (this.index === 0) syncControls(get);
  }

  fitCamera() {
    const c = this.canvas;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(c.clientWidth * dpr);
    const h = Math.round(c.clientHeight * dpr);
    if (c.width !== w || c.height !== h) {
      c.width = w;
      c.height = h;
    }
    // The rest mesh with room around it to drag into.
    const [x0, y0, x1, y1] = this.bounds;
    const pad = 0.6 * Math.max(x1 - x0, y1 - y0);
    const scale = Math.min(w / (x1 - x0 + 2 * pad), h / (y1 - y0 + 2 * pad));
    this.camera = { scale, ox: w / 2 - (scale * (x0 + x1)) / 2, oy: h / 2 + (scale * (y0 + y1)) / 2, dpr };
  }

  toScreen(px, py) {
    const c = this.camera;
    return [c.ox + c.scale * px, c.oy - c.scale * py];
  }

  toWorld(clientX, clientY) {
    const r = this.canvas.getBoundingClientRect();
    const c = this.camera;
    const sx = (clientX - r.left) * c.dpr;
    const sy = (clientY - r.top) * c.dpr;
    return [(sx - c.ox) / c.scale, (c.oy - sy) / c.scale];
  }

  draw(kind) {
    const { x, f32, f64 } = this.io;
    const ctx = this.ctx;
    this.fitCamera();
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    const pos = f32(x.positions());
    const values = f32(x.field(kind));
    // Regions other than the base are drawn flat in the stress map, out of its range.
    const regions = this.regions;
    const flat = kind === 0 && this.hasRegions;
    let hi = -Infinity;
    for (let i = 0; i < values.length; i++) {
      if (flat && regions[i] !== 0) continue;
      if (Number.isFinite(values[i])) hi = Math.max(hi, values[i]);
    }
    const [lo, top] = kind === 2 ? [0, 2] : [0, hi > 0 ? hi : 1];
    // Scenery: ground and obstacles.
    const sc = f64(x.scenery());
    ctx.strokeStyle = "#555";
    ctx.lineWidth = 2;
    if (sc[0] === 1) {
      const [px, py, nx, ny] = [sc[1], sc[2], sc[3], sc[4]];
      ctx.beginPath();
      ctx.moveTo(...this.toScreen(px - ny * 1e3, py + nx * 1e3));
      ctx.lineTo(...this.toScreen(px + ny * 1e3, py - nx * 1e3));
      ctx.stroke();
    }
    let k = 6;
    for (let o = 0; o < sc[5]; o++) {
      const n = sc[k++];
      ctx.beginPath();
      for (let i = 0; i < n; i++) {
        const p = this.toScreen(sc[k + 2 * i], sc[k + 2 * i + 1]);
        if (i === 0) ctx.moveTo(...p);
        else ctx.lineTo(...p);
      }
      k += 2 * n;
      ctx.closePath();
      ctx.fillStyle = "#999";
      ctx.fill();
      ctx.stroke();
    }
    // The body.
    const tri = this.triangles;
    ctx.lineWidth = 0.5;
    ctx.strokeStyle = "rgba(0,0,0,0.25)";
    const edges = tri.length / 3 <= 3000;
    for (let t = 0; t < tri.length / 3; t++) {
      const a = tri[3 * t];
      const b = tri[3 * t + 1];
      const c = tri[3 * t + 2];
      const v = kind === 1 ? (values[a] + values[b] + values[c]) / 3 : values[t];
      ctx.fillStyle = flat && regions[t] !== 0 ? FLAT_COLOUR : Number.isFinite(v) ? palette[kind][Math.min(255, Math.max(0, Math.floor(((v - lo) / (top - lo)) * 256)))] : "#000";
      ctx.beginPath();
      ctx.moveTo(...this.toScreen(pos[2 * a], pos[2 * a + 1]));
      ctx.lineTo(...this.toScreen(pos[2 * b], pos[2 * b + 1]));
      ctx.lineTo(...this.toScreen(pos[2 * c], pos[2 * c + 1]));
      ctx.closePath();
      ctx.fill();
      if (edges) ctx.stroke();
    }
    if (this.hasRegions) this.drawOutline(pos, flat);
    this.drawPressure(pos);
    if (hand.on) {
      ctx.strokeStyle = "#06c";
      ctx.lineWidth = 2;
      const h = this.toScreen(hand.x, hand.y);
      ctx.beginPath();
      ctx.arc(h[0], h[1], 6, 0, 2 * Math.PI);
      ctx.stroke();
    }
    return [lo, top];
  }

  // The material regions' outlines, and (when they are drawn flat) the flat colour's legend
  // at the bottom left.
  drawOutline(pos, flat) {
    const ctx = this.ctx;
    const d = this.camera.dpr;
    const e = this.outline;
    ctx.strokeStyle = OUTLINE_COLOUR;
    ctx.lineWidth = 1.5 * d;
    ctx.beginPath();
    for (let k = 0; k < e.length / 2; k++) {
      const a = e[2 * k];
      const b = e[2 * k + 1];
      ctx.moveTo(...this.toScreen(pos[2 * a], pos[2 * a + 1]));
      ctx.lineTo(...this.toScreen(pos[2 * b], pos[2 * b + 1]));
    }
    ctx.stroke();
    if (!flat) return;
    const [lx, ly, s] = [10 * d, this.canvas.height - 24 * d, 14 * d];
    ctx.fillStyle = FLAT_COLOUR;
    ctx.fillRect(lx, ly, s, s);
    ctx.strokeRect(lx, ly, s, s);
    ctx.fillStyle = "#222";
    ctx.font = `${11 * d}px sans-serif`;
    ctx.fillText(`${this.flatLabel}: drawn flat, out of the stress scale`, lx + s + 6 * d, ly + 11 * d);
  }

  // The contact pressure along the boundary: each loaded boundary edge as a thick line whose
  // colour runs linearly between its ends' pressures, and a legend in kPa at the top left.
  drawPressure(pos) {
    const { x, f32 } = this.io;
    const p = f32(x.contact_pressure());
    let top = 0;
    for (const v of p) if (Number.isFinite(v)) top = Math.max(top, v);
    if (!(top > 0)) return;
    const ctx = this.ctx;
    const e = this.boundary;
    ctx.lineWidth = 5 * this.camera.dpr;
    ctx.lineCap = "round";
    for (let k = 0; k < e.length / 2; k++) {
      const a = e[2 * k];
      const b = e[2 * k + 1];
      if (!(Math.max(p[a], p[b]) > 0)) continue;
      const pa = this.toScreen(pos[2 * a], pos[2 * a + 1]);
      const pb = this.toScreen(pos[2 * b], pos[2 * b + 1]);
      const g = ctx.createLinearGradient(pa[0], pa[1], pb[0], pb[1]);
      g.addColorStop(0, pressureColour(p[a] / top));
      g.addColorStop(1, pressureColour(p[b] / top));
      ctx.strokeStyle = g;
      ctx.beginPath();
      ctx.moveTo(...pa);
      ctx.lineTo(...pb);
      ctx.stroke();
    }
    ctx.lineCap = "butt";
    const d = this.camera.dpr;
    const [lx, ly, lw, lh] = [10 * d, 22 * d, 120 * d, 8 * d];
    const g = ctx.createLinearGradient(lx, 0, lx + lw, 0);
    for (let i = 0; i <= 8; i++) g.addColorStop(i / 8, pressureColour(i / 8));
    ctx.fillStyle = g;
    ctx.fillRect(lx, ly, lw, lh);
    ctx.fillStyle = "#222";
    ctx.font = `${11 * d}px sans-serif`;
    ctx.fillText("contact pressure [kPa]", lx, ly - 4 * d);
    ctx.fillText("0", lx, ly + lh + 11 * d);
    const label = (top / 1000).toPrecision(3);
    ctx.fillText(label, lx + lw - ctx.measureText(label).width, ly + lh + 11 * d);
  }

  hud(fps) {
    const { x, f64, text } = this.io;
    const h = f64(x.hud());
    if (h[15] === 1) showError(`pane ${this.index + 1}: ${text()}`);
    x.names();
    const names = text();
    const force = h[12] === 1 ? `${h[13].toFixed(3)}, ${h[14].toFixed(3)} N` : "-";
    this.hudEl.innerHTML =
      `${names}\n` +
      `t               ${h[0].toFixed(4)} s\n` +
      `steps           ${h[1]}\n` +
      `fps             ${fps.toFixed(1)}\n` +
      `steps/frame     ${h[2]} of ${h[3]}\n` +
      `physics         ${h[4].toFixed(2)} ms/frame\n` +
      `drawing         ${this.drawMs.toFixed(2)} ms/frame\n` +
      `real-time factor ${h[5].toFixed(3)}` +
      (h[6] === 1 ? `  <span class="slow">slowed</span>` : "") +
      `\n` +
      `peak von Mises  ${h[7].toPrecision(4)} Pa\n` +
      (this.hasRegions ? `  of ${this.baseName.padEnd(13)}${h[22].toPrecision(4)} Pa\n` : "") +
      `inverted        ${h[8]}\n` +
      `min det F       ${h[9].toFixed(4)}\n` +
      `area error |dA| ${(100 * h[10]).toFixed(3)} %\n` +
      `area change     ${(100 * h[11]).toFixed(3)} %\n` +
      `contacts        ${h[16]}` +
      (h[16] > 0
        ? `, smallest gap ${(1000 * h[17]).toFixed(3)} mm${h[17] < 0 ? " (penetration)" : ""}, ` +
          `force ${h[18].toFixed(1)}, ${h[19].toFixed(1)} N`
        : "") +
      `\n` +
      `contact pressure ${(h[20] / 1000).toPrecision(4)} kPa peak, length ${h[21].toFixed(4)} m\n` +
      `grab force      ${force}`;
  }
}

// --- Panes, and the controls every pane shares ------------------------------------------------

const first = await instance();
first.x.catalogue();
const [cases, energies, solvers] = first.text().split("\n").map((l) => l.split(" "));
for (const n of cases) $("case").add(new Option(n, n));

const panes = [];
const fem = {
  frames: 0,
  errors: [],
  panes,
  // Pane 0's readers (the browser test's view of the page).
  get exports() {
    return panes[0].io.x;
  },
  hud: (i = 0) => panes[i].io.f64(panes[i].io.x.hud()),
  positions: (i = 0) => panes[i].io.f32(panes[i].io.x.positions()),
  field: (k, i = 0) => panes[i].io.f32(panes[i].io.x.field(k)),
  triangles: (i = 0) => Array.from(panes[i].triangles),
  regions: (i = 0) => Array.from(panes[i].regions),
  names: (i = 0) => (panes[i].io.x.names(), panes[i].io.text()),
  stateHash: (i = 0) => (panes[i].io.x.state_hash(), panes[i].io.text()),
  get view() {
    return panes[0].camera;
  },
  canvas: (i = 0) => panes[i].canvas,
  scenery: (i = 0) => panes[i].io.f64(panes[i].io.x.scenery()),
  addPane: () => addPane(),
  // Set a scene key in every pane (TOML value), as the shared controls do.
  set: (key, value) => panes.every((p) => p.set(key, value)),
  replay: (name, json) => replay(name, json),
  lastDrag: null,
};
window.fem = fem;

// The shared numeric controls and the scene keys they set.
const numeric = {
  dt: "solver.dt",
  substeps: "solver.substeps",
  iterations: "solver.iterations",
  youngs_modulus: "material.youngs_modulus",
  poisson_ratio: "material.poisson_ratio",
  damping: "solver.damping",
};
function syncControls(get) {
  for (const [id, key] of Object.entries(numeric)) {
    const v = get(key);
    $(id).value = v === "" ? "" : Number(v);
    $(id).disabled = v === "";
  }
  // Rigid or elastic bones: the first [[regions]] entry's `rigid` (disabled without regions).
  const bones = get("regions.0.rigid");
  $("bones").value = bones === "" ? "true" : bones;
  $("bones").disabled = bones === "";
}
for (const [id, key] of Object.entries(numeric)) {
  $(id).onchange = (e) => panes.forEach((p) => p.set(key, String(Number(e.target.value))));
}
$("bones").onchange = (e) => panes.forEach((p) => p.set("regions.0.rigid", e.target.value));

// What every pane runs: a built-in case, or a dropped scene (and the files it names).
let source = { kind: "case", name: new URLSearchParams(location.search).get("case") || "case-a" };
const files = [];
function load(pane) {
  for (const f of files) {
    const n = pane.io.named(f.name, f.bytes);
    pane.io.x.add_file(n);
  }
  return source.kind === "case" ? pane.loadCase(source.name) : pane.loadScene(source.name, source.bytes);
}
function loadAll() {
  hand.on = false;
  for (const p of panes) {
    const e = load(p);
    if (e) return showError(e);
  }
  showError("");
}

async function addPane() {
  const p = new Pane(panes.length === 0 ? first : await instance(), panes.length);
  panes.push(p);
  const e = load(p);
  if (e) showError(e);
  // A new pane starts with the first pane's choices, then differs where the user changes it;
  // every pane restarts so that they run side by side from the same start.
  if (panes.length > 1) {
    for (const key of Object.values(numeric).concat(["energy", "solver.kind", "regions.0.rigid"])) {
      const v = panes[0].io.get(key);
      if (v !== "") p.set(key, v);
    }
    hand.on = false;
    panes.forEach((q) => q.io.x.reset());
  }
  layout();
  return p;
}
function removePane(p) {
  const i = panes.indexOf(p);
  if (i > 0) {
    panes.splice(i, 1);
    p.el.remove();
    panes.forEach((q, k) => (q.index = k));
    layout();
  }
}
function layout() {
  $("panes").style.gridTemplateColumns = `repeat(${Math.min(panes.length, 3)}, 1fr)`;
}

$("case").onchange = (e) => {
  source = { kind: "case", name: e.target.value };
  loadAll();
};
$("addpane").onclick = () => addPane();
let paused = false;
$("pause").onclick = () => {
  paused = !paused;
  $("pause").textContent = paused ? "run" : "pause";
};
$("single").onclick = () => {
  paused = true;
  $("pause").textContent = "run";
  for (const p of panes) {
    if (p.io.x.step(1) < 0) showError(p.io.text());
    p.io.x.end_frame(1, 0, 0);
  }
};
$("reset").onclick = () => {
  hand.on = false;
  panes.forEach((p) => p.io.x.reset());
  showError("");
};

// --- Recording and replaying a drag (pane 0 records; a replay drives every pane) ------------

let recording = false;
$("record").onclick = () => {
  const x = panes[0].io.x;
  if (!recording) {
    x.record_start();
    recording = true;
    $("record").textContent = "stop and save drag";
    return;
  }
  x.record_stop();
  recording = false;
  $("record").textContent = "record drag";
  fem.lastDrag = panes[0].io.text();
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([fem.lastDrag], { type: "application/json" }));
  a.download = "drag.json";
  a.click();
};
function replay(name, json) {
  hand.on = false;
  for (const p of panes) {
    const n = p.io.named(name, enc.encode(json));
    if (p.io.x.replay(n) !== 0) return showError(p.io.text());
  }
  showError("");
}

// --- Dropped or picked files ----------------------------------------------------------------

async function loadFile(file) {
  const bytes = new Uint8Array(await file.arrayBuffer());
  const body = dec.decode(bytes);
  if (file.name.endsWith(".json") && /"events"\s*:/.test(body)) {
    // A recorded drag: replay it from the start in every pane.
    return replay(file.name, body);
  }
  if (file.name.endsWith(".json")) {
    // A mesh: keep it, and wrap it in a scene that names it.
    files.push({ name: file.name, bytes });
    const scene =
      `name = "${file.name}"\ngravity = [0.0, -9.8]\n[mesh]\nkind = "file"\npath = "${file.name}"\n` +
      `[material]\nyoungs_modulus = 1000.0\npoisson_ratio = 0.3\ndensity = 1.0\n` +
      `[solver]\nkind = "xpbd"\ndt = 0.01\nsteps = 1000\nsubsteps = 10\n`;
    source = { kind: "scene", name: file.name, bytes: enc.encode(scene) };
  } else {
    source = { kind: "scene", name: file.name, bytes };
  }
  loadAll();
}
$("file").onchange = (e) => e.target.files[0] && loadFile(e.target.files[0]);
const main = $("main");
main.ondragover = (e) => {
  e.preventDefault();
  main.classList.add("dragover");
};
main.ondragleave = () => main.classList.remove("dragover");
main.ondrop = (e) => {
  e.preventDefault();
  main.classList.remove("dragover");
  if (e.dataTransfer.files[0]) loadFile(e.dataTransfer.files[0]);
};

// --- Pointer: one hand for every pane (mouse and touch alike) --------------------------------

const hand = { on: false, x: 0, y: 0 };
function attachPointer(pane) {
  const c = pane.canvas;
  c.addEventListener("pointerdown", (e) => {
    const [wx, wy] = pane.toWorld(e.clientX, e.clientY);
    const stiffness = $("grab").value === "spring" ? Number($("stiffness").value) : 0;
    let any = false;
    for (const p of panes) any = p.io.x.grab_at(wx, wy, stiffness) === 1 || any;
    if (any) {
      Object.assign(hand, { on: true, x: wx, y: wy });
      c.setPointerCapture(e.pointerId);
      c.style.cursor = "grabbing";
    }
  });
  c.addEventListener("pointermove", (e) => {
    if (!hand.on) return;
    [hand.x, hand.y] = pane.toWorld(e.clientX, e.clientY);
    for (const p of panes) p.io.x.drag_to(hand.x, hand.y);
  });
  const letGo = () => {
    if (!hand.on) return;
    hand.on = false;
    for (const p of panes) p.io.x.release();
    c.style.cursor = "grab";
  };
  c.addEventListener("pointerup", letGo);
  c.addEventListener("pointercancel", letGo);
}

// --- The real-time loop ------------------------------------------------------------------------

// Physics may use this much of a frame in all, shared by the panes; the rest is drawing and
// the browser's own work.
const PHYSICS_BUDGET_MS = 12;
let last = null;
let fps = 0;
function frame(now) {
  const wall = last === null ? 1 / 60 : (now - last) / 1000;
  last = now;
  fps = fps === 0 ? 1 / wall : 0.9 * fps + 0.1 / wall;
  const budget = PHYSICS_BUDGET_MS / panes.length;
  const kind = Number($("field").value);
  let range = null;
  for (const p of panes) {
    const x = p.io.x;
    if (!paused) {
      const want = x.begin_frame(wall);
      const t0 = performance.now();
      let done = 0;
      // Steps in growing chunks, so the budget is checked without a clock call per step.
      let chunk = 1;
      while (done < want && performance.now() - t0 < budget) {
        const k = x.step(Math.min(chunk, want - done));
        if (k < 0) {
          showError(`pane ${p.index + 1}: ${p.io.text()}`);
          break;
        }
        done += k;
        chunk = Math.min(chunk * 2, 64);
      }
      x.end_frame(done, performance.now() - t0, wall);
    }
    const d0 = performance.now();
    const r = p.draw(kind);
    if (!range) range = r;
    p.drawMs = 0.9 * p.drawMs + 0.1 * (performance.now() - d0);
    p.hud(fps);
  }
  if (range) drawColorbar(range[0], range[1], kind, ["Pa", "m", ""][kind]);
  fem.frames += 1;
  requestAnimationFrame(frame);
}

function drawColorbar(lo, hi, kind, unit) {
  const cb = $("cb").getContext("2d");
  for (let i = 0; i < 240; i++) {
    cb.fillStyle = colour(i / 239, kind);
    cb.fillRect(i, 0, 1, 14);
  }
  $("lo").textContent = lo.toPrecision(3);
  $("hi").textContent = hi.toPrecision(3) + " " + unit + " (pane 1's scale)";
}

window.addEventListener("error", (e) => fem.errors.push(String(e.message)));
$("case").value = source.name;
await addPane();
requestAnimationFrame(frame);

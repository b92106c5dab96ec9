// The interactive app in a real browser, driven like a person would: headless Chromium (the
// system's) through puppeteer-core. Serves the built site, loads the page, waits for frames,
// drags the cantilever's tip upward with the mouse, and checks that
// - the grabbed vertex followed the pointer (a pinned grab: it sits under the pointer),
// - the stress next to it rose and the heads-up display shows the grab force,
// - switching solver mid-drag keeps the run going (frames and simulated time advance),
// - releasing lets the tip fall back, and the console has no error.
// Then it measures case D in real time (the page's own counters) and saves a screenshot.
//
//   node drag.mjs SITE_DIR [SCREENSHOT.png]   (run by `cargo xtask web --browser-test`)
import http from "node:http";
import { readFile } from "node:fs/promises";
import path from "node:path";
import puppeteer from "puppeteer-core";

const [site, screenshot] = process.argv.slice(2);
const types = { ".html": "text/html", ".js": "text/javascript", ".wasm": "application/wasm" };
const server = http.createServer(async (req, res) => {
  const name = req.url === "/" ? "index.html" : req.url.split("?")[0].slice(1);
  try {
    const body = await readFile(path.join(site, path.basename(name)));
    res.writeHead(200, { "Content-Type": types[path.extname(name)] || "application/octet-stream" });
    res.end(body);
  } catch {
    res.writeHead(404);
    res.end();
  }
});
await new Promise((r) => server.listen(0, "127.0.0.1", r));
const url = `http://127.0.0.1:${server.address().port}/`;

const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? "ok  " : "FAIL"} ${what}`);
  if (!ok) failures.push(what);
};

const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  headless: true,
  args: ["--no-sandbox", "--disable-gpu", "--window-size=1400,900"],
  defaultViewport: { width: 1400, height: 900 },
});
const consoleErrors = [];
try {
  const page = await browser.newPage();
  page.on("console", (m) => m.type() === "error" && consoleErrors.push(m.text()));
  page.on("pageerror", (e) => consoleErrors.push(String(e)));
  await page.goto(url);
  await page.waitForFunction(() => window.fem && window.fem.frames > 10, { timeout: 30000 });
  check(true, "the page runs (frames counted)");

  // Where a world point is on the screen, in CSS pixels.
  const screenOf = (wx, wy) =>
    page.evaluate(
      ([wx, wy]) => {
        const v = window.fem.view;
        const r = document.getElementById("c").getBoundingClientRect();
        return [r.left + (v.ox + v.scale * wx) / v.dpr, r.top + (v.oy - v.scale * wy) / v.dpr];
      },
      [wx, wy],
    );
  const worldOf = (sx, sy) =>
    page.evaluate(
      ([sx, sy]) => {
        const v = window.fem.view;
        const r = document.getElementById("c").getBoundingClientRect();
        return [((sx - r.left) * v.dpr - v.ox) / v.scale, (v.oy - (sy - r.top) * v.dpr) / v.scale];
      },
      [sx, sy],
    );
  const state = () =>
    page.evaluate(() => ({
      x: Array.from(window.fem.positions()),
      vm: Array.from(window.fem.field(0)),
      hud: Array.from(window.fem.hud()),
      frames: window.fem.frames,
      names: window.fem.names(),
      errors: window.fem.errors.slice(),
    }));
  const frames = (n) =>
    page.evaluate(
      (n) =>
        new Promise((resolve) => {
          const until = window.fem.frames + n;
          const wait = () => (window.fem.frames >= until ? resolve() : requestAnimationFrame(wait));
          wait();
        }),
      n,
    );

  // Case A's tip: the right edge at mid-height, vertex (20, 2) of the 21 x 5 grid.
  const tip = 20 * 5 + 2;
  let s = await state();
  const [tx, ty] = [s.x[2 * tip], s.x[2 * tip + 1]];
  const vmBefore = s.vm.slice();
  const [px, py] = await screenOf(tx - 0.02, ty);
  await page.mouse.move(px, py);
  await page.mouse.down();
  const rise = 120;
  for (let k = 1; k <= 30; k++) {
    await page.mouse.move(px, py - (rise * k) / 30);
    await frames(1);
    if (k === 15) {
      // Mid-drag: switch the solver, as a user would with the select box.
      await page.select("#solver", "xpbd");
    }
  }
  await frames(5);
  s = await state();
  const [hx, hy] = await worldOf(px, py - rise);
  const [gx, gy] = [s.x[2 * tip], s.x[2 * tip + 1]];
  // The pointer grabbed 2 cm from the tip, so the tip sits within a few cm of it.
  const off = Math.hypot(gx - hx, gy - hy);
  check(off < 0.05, `the grabbed vertex followed the pointer (${off.toFixed(4)} m off)`);
  check(gy - ty > 0.5, `the tip rose ${(gy - ty).toFixed(3)} m`);
  check(s.hud[12] === 1, `the grab force is shown (${s.hud[13].toFixed(2)}, ${s.hud[14].toFixed(2)} N)`);
  const near = [];
  // Triangles touching the tip: the stress there rose.
  const tris = await page.evaluate(() => Array.from(window.fem.exports.triangles ? (() => {
    const x = window.fem.exports;
    const p = x.triangles();
    return new Uint32Array(x.memory.buffer, p, x.out_len()).slice();
  })() : []));
  for (let t = 0; t < tris.length / 3; t++) {
    if ([tris[3 * t], tris[3 * t + 1], tris[3 * t + 2]].includes(tip)) near.push(t);
  }
  const rose = near.filter((t) => s.vm[t] > vmBefore[t] + 1).length;
  check(near.length > 0 && rose === near.length, `stress rose in ${rose} of the ${near.length} triangles at the tip`);
  check(s.names.endsWith("xpbd"), `switched solver mid-drag: ${s.names}`);
  const t1 = s.hud[0];
  const f1 = s.frames;
  await frames(10);
  s = await state();
  check(s.hud[0] > t1 && s.frames >= f1 + 10, "after the switch, time and frames advance");
  await page.mouse.up();
  await frames(20);
  s = await state();
  check(s.x[2 * tip + 1] < gy, "released, the tip falls back");
  check(s.hud[12] === 0, "released, no grab force");
  if (screenshot) {
    // The picture for docs/interactive.md: drag again and shoot mid-drag.
    await page.mouse.move(px, py);
    await page.mouse.down();
    for (let k = 1; k <= 20; k++) {
      await page.mouse.move(px - k, py - (rise * k) / 20);
      await frames(1);
    }
    await page.screenshot({ path: screenshot });
    await page.mouse.up();
    console.log(`screenshot: ${screenshot}`);
  }

  // Case D in real time (explicit Neo-Hookean at its own dt): the page's counters.
  await page.select("#case", "case-d");
  await frames(30);
  const hud = await page.evaluate(async () => {
    const rows = [];
    for (let i = 0; i < 60; i++) {
      await new Promise((r) => requestAnimationFrame(r));
      rows.push(Array.from(window.fem.hud()));
    }
    return rows;
  });
  const mean = (i) => hud.reduce((a, r) => a + r[i], 0) / hud.length;
  const slowed = hud.filter((r) => r[6] === 1).length;
  console.log(
    `case D: ${mean(2).toFixed(1)} steps a frame (of ${mean(3).toFixed(1)} wanted), ` +
      `physics ${mean(4).toFixed(2)} ms a frame, real-time factor ${mean(5).toFixed(3)}, ` +
      `${slowed} of ${hud.length} frames slowed`,
  );
  s = await state();
  check(s.errors.length === 0, `no error on the page (${s.errors.join("; ")})`);
} finally {
  await browser.close();
  server.close();
}
check(consoleErrors.length === 0, `console has no error (${consoleErrors.join("; ")})`);
if (failures.length) {
  console.error(`${failures.length} check(s) failed`);
  process.exit(1);
}

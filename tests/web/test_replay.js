#!/usr/bin/env node
// The `pinsim replay` page in a real browser (ctest: "web: replay page fits the window
// (BROWSER)"): a 2 s run of the pinball table is turned into a page, which is opened at
// 1280x900, 800x600 and 800x600 with device pixel ratio 2. At each size: no page error, the
// canvas and every control wholly inside the window with no scrolling, the canvas at the
// largest size that keeps the table's aspect ratio (it touches the window's sides or the bar)
// - also after the 1280x900 window is resized to 800x500 -,
// its backing store devicePixelRatio times its CSS size, playback advances, Space pauses it,
// and the canvas's screenshot is not blank. A crowded run (400 balls) starts with trails and
// contact flashes off, the pinball's with them on.
//
// Usage: test_replay.js BROWSER --pinsim BIN --scene SCENE.json   (makes the run and page)
//        test_replay.js BROWSER --page FILE.html                  (checks an existing page)
// Exit 0 pass, 1 fail, 2 bad usage, 77 skip (no puppeteer-core or no such browser).
"use strict";

const { execFileSync } = require("child_process");
const path = require("path");
const web = require("./harness");

const SIZES = [
  { width: 1280, height: 900, dpr: 1 },
  { width: 800, height: 600, dpr: 1 },
  { width: 800, height: 600, dpr: 2 },
];
const CONTROLS = ["#view", "#bar", "#play", "#scrub", "#time", "#speed", "#trails", "#flashes"];

function parseArgs(argv) {
  const o = { browser: argv[0], pinsim: null, scene: null, page: null };
  for (let i = 1; i < argv.length; i += 2) {
    const v = argv[i + 1];
    if (v === undefined) usage(`${argv[i]} needs a value`);
    if (argv[i] === "--pinsim") o.pinsim = v;
    else if (argv[i] === "--scene") o.scene = v;
    else if (argv[i] === "--page") o.page = v;
    else usage(`unknown option ${argv[i]}`);
  }
  if (!["chromium", "firefox"].includes(o.browser)) usage("the first argument is chromium or firefox");
  if (!o.page && !(o.pinsim && o.scene)) usage("give --page, or --pinsim and --scene");
  return o;
}

function usage(msg) {
  console.error(`test_replay.js: ${msg}\nusage: test_replay.js BROWSER (--page FILE | --pinsim BIN --scene FILE)`);
  process.exit(2);
}

/** Runs the scene for 2 s of simulated time and writes its replay page; returns the page. */
function makePage(pinsim, scene) {
  const dir = web.tempDir("pinsim-replay-web");
  const run = path.join(dir, "run");
  execFileSync(pinsim, ["-q", "run", scene, "--out", run, "--overwrite", "--set", "time.duration=2"],
               { stdio: "inherit" });
  const page = path.join(dir, "replay.html");
  execFileSync(pinsim, ["-q", "replay", run, "--out", page], { stdio: "inherit" });
  return page;
}

/** A crowded run: 400 balls of 1 cm dropped into a box for 0.3 s, and its replay page. */
function makeCrowdedPage(pinsim) {
  const dir = web.tempDir("pinsim-replay-crowd");
  const particles = [];
  for (let i = 0; i < 20; ++i)
    for (let j = 0; j < 20; ++j)
      particles.push({ x: [0.05 + 0.045 * i, 0.3 + 0.045 * j], v: [0.3 * ((i + j) % 3 - 1), 0],
                       radius: 0.01 });
  const scene = {
    name: "crowd", time: { dt: 0.001, duration: 0.3 }, backend: { name: "sdf" },
    particles, forces: [{ type: "gravity" }],
    obstacles: [{ id: "box", shape: { type: "inside", shape: { type: "box", center: [0.5, 0.6],
                                                                   half_size: [0.5, 0.6] } } }],
    output: { every: 10 },
  };
  const file = path.join(dir, "crowd.json");
  require("fs").writeFileSync(file, JSON.stringify(scene));
  const run = path.join(dir, "run");
  execFileSync(pinsim, ["-q", "run", file, "--out", run, "--overwrite"], { stdio: "inherit" });
  const page = path.join(dir, "crowd.html");
  execFileSync(pinsim, ["-q", "replay", run, "--out", page], { stdio: "inherit" });
  return page;
}

/** Trails and contact flashes start on for the pinball, off for the crowd (then ?trails=1). */
async function checkCrowd(browser, pinball, crowd) {
  const boxes = () => ({ trails: document.getElementById("trails").checked,
                         flashes: document.getElementById("flashes").checked,
                         crowded: document.body.dataset.crowded });
  for (const [file, query, want] of [[pinball, "", { trails: true, flashes: true, crowded: "0" }],
                                     [crowd, "", { trails: false, flashes: false, crowded: "1" }],
                                     [crowd, "?trails=1", { trails: true, flashes: false, crowded: "1" }]]) {
    const page = await browser.open(file, { width: 1280, height: 900, query });
    try {
      await page.waitForData((d) => d.status === "ok", { what: "data-status ok" });
      const got = await page.evaluate(boxes);
      if (JSON.stringify(got) !== JSON.stringify(want))
        throw new web.CheckFailed(`${path.basename(file)}${query}: ${JSON.stringify(got)}, expected ${JSON.stringify(want)}`);
      await page.checkNotBlank({ selector: "#view" });
      await page.checkErrors();
    } finally {
      await page.close();
    }
  }
  console.log("crowded replay: trails and contacts off by default, on by query; the pinball's on");
}

function near(a, b, tol, what) {
  if (!(Math.abs(a - b) <= tol)) throw new web.CheckFailed(`${what}: ${a} vs ${b} (tolerance ${tol})`);
}

/** Checks the canvas's fit in the page's current window (see the file's comment). */
async function checkFit(page) {
  const tag = page.describe().split(" file:")[0];
  await page.checkInViewport(CONTROLS);
  const d0 = await page.data();
  // The fit. The map's size comes from the page's own data (the canvas's pixel grid).
  const g = await page.evaluate(() => {
    const c = document.getElementById("view").getBoundingClientRect();
    const bar = document.getElementById("bar").getBoundingClientRect();
    const v = document.getElementById("view");
    return { cssW: c.width, cssH: c.height, barH: bar.height, barTop: bar.top, canvasBottom: c.bottom,
             backW: v.width, backH: v.height, vw: innerWidth, vh: innerHeight, dpr: devicePixelRatio,
             mapW: DATA.map.width, mapH: DATA.map.height };
  });
  const s = Number(d0.scale);
  // Largest scale s with s*mapW <= vw and s*mapH <= vh - bar (the CSS size is s * map size,
  // floored to whole pixels, so within 1 px).
  near(s, Math.min(g.vw / g.mapW, (g.vh - g.barH) / g.mapH), 1e-4, `${tag}: data-scale`);
  near(g.cssW, g.mapW * s, 1, `${tag}: canvas CSS width`);
  near(g.cssH, g.mapH * s, 1, `${tag}: canvas CSS height`);
  const touches = Math.abs(g.cssW - g.vw) <= 1 || Math.abs(g.cssH - (g.vh - g.barH)) <= 1;
  if (!touches) throw new web.CheckFailed(`${tag}: the canvas ${g.cssW}x${g.cssH} does not fill the window`);
  if (g.barTop + 0.5 < g.canvasBottom) throw new web.CheckFailed(`${tag}: the bar overlaps the canvas`);
  near(g.dpr, page.dpr, 1e-9, `${tag}: devicePixelRatio`);
  near(g.backW, g.cssW * g.dpr, 1, `${tag}: canvas backing width`);
  near(g.backH, g.cssH * g.dpr, 1, `${tag}: canvas backing height`);
  console.log(`${tag}: map ${g.mapW}x${g.mapH} shown at ${g.cssW}x${g.cssH} CSS px (scale ${s}), ` +
              `backing ${g.backW}x${g.backH}, bar ${g.barH.toFixed(0)} px; controls in the window`);
}

async function checkSize(browser, file, size, shots) {
  // At a quarter speed the 2 s run lasts 8 s of wall clock: the checks end well before it
  // stops by itself at its end (where Space would restart it).
  const page = await browser.open(file, Object.assign({ query: "?speed=0.25" }, size));
  const tag = page.describe().split(" file:")[0];
  try {
    const d0 = await page.waitForData((d) => d.status === "ok", { what: "data-status ok" });
    await checkFit(page);
    if (size.width === 1280) {
      // The page refits when the window changes: shrink this one to 800 x 500.
      await page.resize(800, 500);
      await page.waitForData((d) => d.scale !== d0.scale, { what: "data-scale changes on resize" });
      await checkFit(page);
      await page.resize(size.width, size.height);
      await page.waitForData((d) => d.scale === d0.scale, { what: "data-scale back after resize" });
    }

    // Playback advances by itself, and Space pauses it.
    const t0 = Number((await page.data()).t);
    const d1 = await page.waitForData((d) => Number(d.t) > t0 + 0.05, { what: `data-t > ${t0} + 0.05` });
    await page.press("Space", 30);
    await page.sleep(100);  // let the keydown's frame pass
    const tp = (await page.data()).t;
    await page.sleep(300);
    const tq = (await page.data()).t;
    if (tp !== tq) throw new web.CheckFailed(`${tag}: still playing after Space: t ${tp} -> ${tq}`);
    const label = await page.evaluate(() => document.getElementById("play").textContent);
    if (label !== "Play") throw new web.CheckFailed(`${tag}: the play button says "${label}" after Space`);
    console.log(`${tag}: t advanced ${t0} -> ${d1.t} s; paused by Space at t = ${tp} s`);

    const file2 = shots ? path.join(shots, `${browser.name}-${size.width}x${size.height}@${size.dpr}.png`) : null;
    const st = await page.checkNotBlank({ selector: "#view", file: file2 });
    console.log(`${tag}: canvas screenshot ${st.width}x${st.height}: ${(100 * st.foreground).toFixed(1)}% ` +
                `differs from ${st.background}, ${st.colours} colours`);
    await page.checkErrors();
  } finally {
    await page.close();
  }
}

(async () => {
  const o = parseArgs(process.argv.slice(2));
  if (!web.available(o.browser)) {
    console.log(`SKIPPED: ${web.whyUnavailable(o.browser)}`);
    process.exit(web.SKIP);
  }
  const file = o.page || makePage(o.pinsim, o.scene);
  const shots = process.env.PINSIM_WEB_SHOTS || null;  // keep the screenshots there
  if (shots) require("fs").mkdirSync(shots, { recursive: true });
  const crowd = o.pinsim ? makeCrowdedPage(o.pinsim) : null;
  await web.eachBrowser([o.browser], async (b) => {
    for (const size of SIZES) await checkSize(b, file, size, shots);
    if (crowd) await checkCrowd(b, file, crowd);
  });
  console.log("test_replay: passed");
})().catch((e) => {
  console.error("FAILED: " + (e && e.stack ? e.stack : e));
  process.exit(1);
});

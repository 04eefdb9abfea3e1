// `pinsim share`'s page in a headless browser (tests/web harness): the engine runs, keys
// play the game, the page's state hash agrees with a native rerun of its recording, a native
// recording rerun in the page reaches the native hash, the table is drawn, no page error.
// Usage: node test_share_page.js BROWSER --pinsim BIN --scene S [--page HTML]
//   --page: a page already made (`pinsim share --source`); otherwise `pinsim share S` makes it.
"use strict";
const fs = require("fs");
const path = require("path");
const { spawnSync } = require("child_process");
const web = require("../web/harness");

function arg(name, def) {
  const i = process.argv.indexOf("--" + name);
  return i >= 0 ? process.argv[i + 1] : def;
}
const browserName = process.argv[2] || "chromium";
const pinsim = arg("pinsim"), scene = arg("scene"), givenPage = arg("page");

async function main() {
  if (!web.available(browserName)) {
    console.log("SKIPPED: " + web.whyUnavailable(browserName));
    return web.SKIP;
  }
  const tmp = web.tempDir("share");
  const pageFile = givenPage || path.join(tmp, "game.html");
  if (!givenPage) {
    const share = spawnSync(pinsim, ["-q", "share", scene, "--out", pageFile], { encoding: "utf8" });
    if (share.status !== 0) {
      if (/is not built/.test(share.stderr)) {
        console.log("SKIPPED: " + share.stderr.trim());
        return web.SKIP;
      }
      throw new Error("pinsim share failed: " + share.stderr);
    }
  }
  const size = fs.statSync(pageFile).size;
  console.log(`page ${pageFile}: ${(size / 1024).toFixed(0)} kB`);
  if (size > 2 * 1024 * 1024) throw new Error(`the page is ${size} bytes, more than 2 MB`);

  const browser = await web.launch(browserName);
  try {
    const page = await browser.open(pageFile, { width: 1280, height: 900 });
    await page.waitForData((d) => d.status === "ready", { what: "status ready", timeout: 30000 });
    // The bar is one line at 1280 px: every control inside its 34 px, side by side, none
    // wrapped (a wrapped text is taller than one line of its 14 px font).
    const bar = await page.evaluate(() => {
      const b = document.getElementById("bar").getBoundingClientRect();
      return Array.from(document.querySelectorAll("#bar > *"))
        .filter((e) => e.offsetParent !== null)
        .map((e) => { const r = e.getBoundingClientRect();
                      return { id: e.id || e.tagName, top: r.top - b.top, bottom: r.bottom - b.top,
                               height: r.height, right: r.right, width: b.width }; });
    });
    for (const e of bar)
      if (e.top < 0 || e.bottom > 34 || e.height > 30 || e.right > e.width + 0.5)
        throw new Error("the header bar wraps or overflows at 1280 px: " + JSON.stringify(bar));
    // Play: pull the plunger 0.7 s, flip both flippers a few times.
    await page.press("Space", 700);
    for (let k = 0; k < 4; ++k) {
      await page.press(k % 2 ? "KeyM" : "KeyZ", 120);
      await page.sleep(150);
    }
    await page.press("ArrowLeft", 100);
    await page.waitForData((d) => Number(d.steps) > 20000, { what: "steps > 20000", timeout: 30000 });
    await page.evaluate(() => window.pinsimPage.pause());
    const d = await page.data();
    const rec = JSON.parse(await page.evaluate(() => window.pinsimPage.recording()));
    console.log(`page: ${d.steps} steps, score ${d.score}, hash ${d.stateHash}, ${rec.inputs.length} inputs`);
    if (rec.state_hash !== d.stateHash || String(rec.steps) !== d.steps)
      throw new Error("the recording's hash/steps differ from the page's data- attributes");
    if (!rec.inputs.some((i) => i.input === "plunger") ||
        !rec.inputs.some((i) => i.input === "left") || !rec.inputs.some((i) => i.input === "right"))
      throw new Error("the keys did not reach the game: " + JSON.stringify(rec.inputs));
    const recFile = path.join(tmp, "page_recording.json");
    fs.writeFileSync(recFile, JSON.stringify(rec, null, 2));
    const native = spawnSync(pinsim, ["-q", "play", scene, "--rerun", recFile], { encoding: "utf8" });
    console.log("native: " + native.stdout.trim());
    if (native.status !== 0 || !native.stdout.includes(rec.state_hash + " "))
      throw new Error("pinsim play --rerun of the page's recording does not reach the page's hash");

    await page.checkNotBlank({ selector: "#table", file: process.env.PINSIM_WEB_SHOTS
      ? path.join(process.env.PINSIM_WEB_SHOTS, "share_" + browserName + ".png") : null });

    // A native recording rerun in the page.
    const script = [{ t: 0.05, input: "plunger", action: "press" },
                    { t: 0.6, input: "plunger", action: "release" },
                    { t: 2.0, input: "left", action: "press" },
                    { t: 2.2, input: "left", action: "release" }];
    const scriptFile = path.join(tmp, "script.json"), nativeRec = path.join(tmp, "native.json");
    fs.writeFileSync(scriptFile, JSON.stringify(script));
    const play = spawnSync(pinsim, ["-q", "play", scene, "--script", scriptFile, "--seconds", "4",
                                    "--record", nativeRec],
                           { encoding: "utf8", env: { ...process.env, SDL_VIDEODRIVER: "dummy" } });
    if (play.status !== 0) throw new Error("pinsim play --record failed: " + play.stderr);
    const nrec = fs.readFileSync(nativeRec, "utf8");
    const s = await page.evaluate((text) => window.pinsimPage.rerun(text), nrec);
    const d2 = await page.data();
    const want = JSON.parse(nrec);
    console.log(`page rerun of the native recording: hash ${d2.stateHash} (native ${want.state_hash})`);
    if (d2.stateHash !== want.state_hash || s.score !== want.score)
      throw new Error("the page's rerun of a native recording differs from it");
    await page.checkErrors();
    await page.close();
  } finally {
    await browser.close();
  }
  console.log("ok");
  return 0;
}

main().then((rc) => process.exit(rc), (e) => { console.error("FAIL " + (e.stack || e)); process.exit(1); });

// Benchmark (not a test): time of one frame of `pinsim share`'s page - 1/60 s of simulation
// at the scene's dt, round(1/60/dt) engine steps - in headless Chromium (or Firefox), on the
// page itself (tests/web harness). The game is played first (plunger shot) so the ball is
// moving and colliding, then the live loop is paused and window.pinsimPage.benchFrame(N)
// steps N frames back to back and reports the mean. Prints the page size too.
// Usage: node bench/web/share_frame_time.js PAGE.html [--browser chromium] [--frames 300]
//        (make the page with `pinsim share configs/pinball.json --out PAGE.html`;
//         needs tests/web/node_modules, i.e. scripts/setup.sh)
"use strict";
const fs = require("fs");
const web = require("../../tests/web/harness");

function arg(name, def) {
  const i = process.argv.indexOf("--" + name);
  return i >= 0 ? process.argv[i + 1] : def;
}

async function main() {
  const pageFile = process.argv[2];
  const browserName = arg("browser", "chromium"), frames = Number(arg("frames", "300"));
  if (!pageFile || !fs.existsSync(pageFile)) throw new Error("usage: share_frame_time.js PAGE.html");
  const browser = await web.launch(browserName);
  try {
    const page = await browser.open(pageFile, { width: 1280, height: 900 });
    await page.waitForData((d) => d.status === "ready", { what: "ready", timeout: 30000 });
    await page.press("Space", 700);
    await page.sleep(1500);
    await page.evaluate(() => window.pinsimPage.pause());
    // Warm-up (JIT tiers of the wasm), then the measurement, three times.
    await page.evaluate((n) => window.pinsimPage.benchFrame(n), 60);
    const runs = [];
    for (let k = 0; k < 3; ++k)
      runs.push(await page.evaluate((n) => window.pinsimPage.benchFrame(n), frames));
    await page.checkErrors();
    const ms = runs.map((r) => r.ms_per_frame);
    console.log(`page ${pageFile}: ${(fs.statSync(pageFile).size / 1048576).toFixed(2)} MB`);
    console.log(`${browserName}: ${runs[0].steps_per_frame} steps per frame (1/60 s), ` +
                `${frames} frames x 3: ms per frame ${ms.map((v) => v.toFixed(3)).join(", ")} ` +
                `(min ${Math.min(...ms).toFixed(3)}; budget 4 ms)`);
  } finally {
    await browser.close();
  }
}
main().catch((e) => { console.error(e.stack || String(e)); process.exit(1); });

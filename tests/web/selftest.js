#!/usr/bin/env node
// The harness's own test (ctest: web_harness_selftest): every check must pass on a good page
// and fail on a page made bad on purpose (fixtures/probe.html), in Chromium and, when it is
// installed, Firefox. Usage: selftest.js [chromium] [firefox]. Exit 0 pass, 1 fail, 77 skip (no
// puppeteer-core, or the first browser named is not installed).
"use strict";

const path = require("path");
const h = require("./harness");

const PROBE = path.join(__dirname, "fixtures", "probe.html");

/** Fails unless `promise` rejects with a CheckFailed whose message matches `re`. */
async function mustFail(what, promise, re) {
  try {
    await promise;
  } catch (e) {
    if (!(e instanceof h.CheckFailed)) throw e;
    if (!re.test(e.message)) throw new Error(`${what}: failed with an unexpected message: ${e.message}`);
    console.log(`  ok: ${what} fails: ${e.message.slice(0, 160)}`);
    return;
  }
  throw new Error(`${what}: the check passed but must fail`);
}

async function withPage(b, query, body, size = { width: 640, height: 400 }) {
  const t0 = Date.now();
  const p = await b.open(PROBE, Object.assign({ query }, size));
  try {
    await body(p);
  } finally {
    await p.close();
  }
  console.log(`  (${b.name}: probe.html${query} took ${Date.now() - t0} ms)`);
}

async function suite(b) {
  // A good page: loads, draws, keys land with their hold time, no errors.
  await withPage(b, "", async (p) => {
    await p.waitForData((d) => d.status === "ok" && Number(d.frames) > 2, { what: "status ok" });
    await p.checkInViewport(["#view", "#box"]);
    const s = await p.checkNotBlank({ selector: "#view" });
    console.log(`  ok: drawn canvas: ${(100 * s.foreground).toFixed(1)}% foreground, ${s.colours} colours`);
    await p.press("Space", 300);
    await p.keys([{ key: "KeyZ", down: 0 }, { key: "KeyZ", up: 120 }, { wait: 20 }]);
    const d = await p.waitForData((d) => d.keys === "+Space-Space+KeyZ-KeyZ", { what: "keys", timeout: 3000 });
    // The last hold was 120 ms of wall clock between the two key events (a lower bound:
    // the page sees the events no closer together than they were sent).
    if (!(Number(d.heldMs) >= 100)) throw new Error(`held ${d.heldMs} ms, expected >= 100`);
    console.log(`  ok: keys ${d.keys}, last held ${d.heldMs} ms`);
    await p.checkErrors();
    await mustFail("a condition never met", p.waitForData((d) => d.status === "never", { timeout: 300, what: "status never" }), /timed out .* status never/);
  });
  // Bad pages: each check must fail, and name every fault (one page holds several faults
  // to keep the browser time down).
  await withPage(b, "?blank=1&offscreen=1", async (p) => {
    await mustFail("a blank canvas", p.checkNotBlank({ selector: "#view" }), /#view looks blank/);
    await mustFail("an element below the window", p.checkInViewport(["#view", "#box"]), /#box .* outside/);
  });
  await withPage(b, "?error=1&console=1&dataerror=1", async (p) => {
    await p.sleep(200);
    await mustFail("an uncaught error, a console error, a data-error attribute", p.checkErrors(),
                   /(?=.*page error: .*probe: an uncaught error)(?=.*console error: probe: a console error)(?=.*data-error: probe: data-error set)/);
  });
  // A page that is not there: the navigation itself fails (not a CheckFailed).
  let opened = null;
  try {
    opened = await b.open(PROBE + ".missing");
  } catch (e) {
    if (!/ERR_FILE_NOT_FOUND|NS_ERROR_FILE_NOT_FOUND/.test(e.message)) throw e;
    console.log(`  ok: a missing file fails: ${e.message.slice(0, 100)}`);
  }
  if (opened) throw new Error("a missing file opened without an error");
}

(async () => {
  const first = process.argv[2] || "chromium";
  if (!h.available(first)) {
    console.log(`SKIPPED: ${h.whyUnavailable(first)}`);
    process.exit(h.SKIP);
  }
  // Browsers: the arguments (chromium, firefox), default both; ctest runs one per test.
  const names = process.argv.length > 2 ? process.argv.slice(2) : ["chromium", "firefox"];
  const ran = await h.eachBrowser(names, suite);
  console.log(`selftest: passed in ${ran.join(", ")}`);
})().catch((e) => {
  console.error("FAILED: " + (e && e.stack ? e.stack : e));
  process.exit(1);
});

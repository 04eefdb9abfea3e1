// Headless-browser harness for pinsim's web pages (the `replay` page, the `share` page):
// opens a file:// page in headless Chromium or Firefox at a given window size, fails on any
// page error, console error, failed request or data-error attribute, presses keys with
// timing, waits for data- attribute conditions, checks that elements are inside the viewport
// and that a screenshot is not blank. API and thresholds: tests/web/README.md.
"use strict";

const fs = require("fs");
const os = require("os");
const path = require("path");
const url = require("url");

// Exit code ctest treats as "skipped" (SKIP_RETURN_CODE in the test registration).
const SKIP = 77;

const BROWSERS = {
  chromium: { puppeteer: "chrome", executables: ["/usr/bin/chromium", "/usr/bin/chromium-browser"] },
  firefox: { puppeteer: "firefox", executables: ["/usr/bin/firefox-esr", "/usr/bin/firefox"] },
};

/** Thrown when the harness cannot run at all (no puppeteer-core, no browser): a skip. */
class Unavailable extends Error {}

/** Thrown when a page check fails (a test failure). */
class CheckFailed extends Error {}

function loadPuppeteer() {
  try {
    return require("puppeteer-core");
  } catch (e) {
    throw new Unavailable(
      "puppeteer-core is not installed in tests/web/node_modules (scripts/setup.sh runs `npm ci` there)");
  }
}

/** The browser's executable: $PINSIM_CHROMIUM / $PINSIM_FIREFOX, else the Debian paths. */
function executable(name) {
  const spec = BROWSERS[name];
  if (!spec) throw new Error(`unknown browser "${name}" (expected chromium or firefox)`);
  const env = process.env[name === "chromium" ? "PINSIM_CHROMIUM" : "PINSIM_FIREFOX"];
  const candidates = env ? [env] : spec.executables;
  for (const c of candidates) if (fs.existsSync(c)) return c;
  throw new Unavailable(`${name} is not installed (looked for ${candidates.join(", ")})`);
}

/** Whether `name` can be launched here (puppeteer-core and the executable exist). */
function available(name) {
  try {
    loadPuppeteer();
    executable(name);
    return true;
  } catch (e) {
    if (e instanceof Unavailable) return false;
    throw e;
  }
}

/**
 * Launches one headless browser; open many pages in it (one launch per test file).
 * Chromium: new headless mode; --no-sandbox only when running as root (Chromium refuses to
 * start its sandbox as root, e.g. in a container) or when PINSIM_WEB_NO_SANDBOX=1.
 * Firefox: driven over WebDriver BiDi (puppeteer-core 24's only Firefox protocol).
 */
async function launch(name = "chromium", options = {}) {
  const puppeteer = loadPuppeteer();
  const exe = executable(name);
  const args = [];
  if (name === "chromium") {
    const root = typeof process.getuid === "function" && process.getuid() === 0;
    if (root || process.env.PINSIM_WEB_NO_SANDBOX === "1") args.push("--no-sandbox");
    args.push("--disable-dev-shm-usage", "--no-first-run", "--disable-background-networking",
              "--disable-component-update", "--disable-sync");
  }
  const browser = await puppeteer.launch({
    browser: BROWSERS[name].puppeteer,
    executablePath: exe,
    headless: true,  // Chromium: the new headless mode (the full browser without a window)
    args: args.concat(options.args || []),
    defaultViewport: null,
    timeout: options.timeout || 30000,
  });
  return new Browser(name, browser);
}

class Browser {
  constructor(name, browser) {
    this.name = name;
    this.browser = browser;
  }

  version() {
    return this.browser.version();
  }

  /**
   * Opens `target` (a file path, or a URL) at width x height CSS pixels and device pixel
   * ratio `dpr`; `query` (e.g. "?t=0.5") is appended to a file path. Resolves once the page
   * has loaded; errors seen from then on are collected (see Page.errors).
   */
  async open(target, { width = 1280, height = 900, dpr = 1, query = "", timeout = 15000 } = {}) {
    const page = await this.browser.newPage();
    const p = new Page(this, page, width, height, dpr);
    await page.setViewport({ width, height, deviceScaleFactor: dpr });
    const href = /^[a-z]+:/.test(target) ? target : url.pathToFileURL(path.resolve(target)).href + query;
    p.url = href;
    await page.goto(href, { waitUntil: "load", timeout });
    return p;
  }

  close() {
    return this.browser.close();
  }
}

const keyName = (key) => (key === "Space" ? " " : key);

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

class Page {
  constructor(browser, page, width, height, dpr) {
    this.browser = browser;
    this.page = page;
    this.width = width;
    this.height = height;
    this.dpr = dpr;
    /** Every page error, console error and failed request, as text, in order. */
    this.errors = [];
    page.on("pageerror", (e) => this.errors.push("page error: " + (e && e.message ? e.message : e)));
    page.on("console", (m) => {
      if (m.type() === "error") this.errors.push("console error: " + m.text());
    });
    page.on("requestfailed", (r) => {
      const f = r.failure();
      this.errors.push("request failed: " + r.url().slice(0, 200) + (f ? " (" + f.errorText + ")" : ""));
    });
  }

  /** Fails (CheckFailed) if any error was seen or any element has a non-empty data-error. */
  async checkErrors() {
    const attr = await this.page.evaluate(() =>
      Array.from(document.querySelectorAll("[data-error]"))
        .map((e) => e.getAttribute("data-error"))
        .filter((v) => v));
    const all = this.errors.concat(attr.map((v) => "data-error: " + v));
    if (all.length) throw new CheckFailed(`${this.describe()}: ${all.join("; ")}`);
  }

  describe() {
    return `${this.browser.name} ${this.width}x${this.height}@${this.dpr} ${this.url.slice(0, 120)}`;
  }

  /** The data- attributes of the first element matching `selector` (default body), camelCased as dataset. */
  async data(selector = "body") {
    const d = await this.page.evaluate((s) => {
      const e = document.querySelector(s);
      return e ? Object.assign({}, e.dataset) : null;
    }, selector);
    if (d === null) throw new CheckFailed(`${this.describe()}: no element matches ${selector}`);
    return d;
  }

  /**
   * Waits until `predicate(data)` is true for the data- attributes of `selector`, polling
   * every `interval` ms; checks errors at each poll. Returns the data that satisfied it.
   * `what` names the condition in the failure message.
   */
  async waitForData(predicate, { selector = "body", timeout = 10000, interval = 50, what = "" } = {}) {
    const t0 = Date.now();
    let d = null;
    for (;;) {
      await this.checkErrors();
      d = await this.data(selector);
      if (predicate(d)) return d;
      if (Date.now() - t0 > timeout) {
        throw new CheckFailed(`${this.describe()}: timed out after ${timeout} ms waiting for ` +
                              `${what || predicate.toString()}; data: ${JSON.stringify(d)}`);
      }
      await sleep(interval);
    }
  }

  /**
   * Key down: a puppeteer key name ("ArrowLeft", "KeyZ", "Enter", "ShiftRight", ...) or one
   * character. "Space" is sent as " ": Firefox's WebDriver BiDi keyboard in puppeteer-core
   * 24 knows no "Space" name, and " " gives code "Space" in both browsers.
   */
  keyDown(key) {
    return this.page.keyboard.down(keyName(key));
  }

  keyUp(key) {
    return this.page.keyboard.up(keyName(key));
  }

  /** Presses `key`, holds it `holdMs` milliseconds (wall clock), releases it. */
  async press(key, holdMs = 50) {
    await this.keyDown(key);
    await sleep(holdMs);
    await this.keyUp(key);
  }

  /**
   * Plays a key script: [{key, down: ms}, {key, up: ms}, {wait: ms}] - each step waits its
   * ms after the previous step, then acts. Returns when the last step is done.
   */
  async keys(script) {
    for (const s of script) {
      const ms = s.down ?? s.up ?? s.wait ?? 0;
      if (ms > 0) await sleep(ms);
      if (s.down !== undefined) await this.keyDown(s.key);
      else if (s.up !== undefined) await this.keyUp(s.key);
    }
  }

  sleep(ms) {
    return sleep(ms);
  }

  /** Resizes the window (viewport) to width x height CSS pixels at device pixel ratio dpr. */
  async resize(width, height, dpr = this.dpr) {
    await this.page.setViewport({ width, height, deviceScaleFactor: dpr });
    this.width = width;
    this.height = height;
    this.dpr = dpr;
  }

  /** Runs `fn(...args)` in the page (puppeteer's evaluate). */
  evaluate(fn, ...args) {
    return this.page.evaluate(fn, ...args);
  }

  /**
   * Each selector's bounding box (CSS pixels) and whether it lies wholly inside the viewport
   * (window.innerWidth x innerHeight, tolerance 0.5 px for fractional layout); fails if an
   * element is missing, has zero size or sticks out. Also fails if the page scrolls (the
   * document is larger than the viewport), unless allowScroll.
   */
  async checkInViewport(selectors, { allowScroll = false } = {}) {
    const r = await this.page.evaluate((sels) => {
      const out = { vw: window.innerWidth, vh: window.innerHeight,
                    sw: document.documentElement.scrollWidth, sh: document.documentElement.scrollHeight,
                    boxes: {} };
      for (const s of sels) {
        const e = document.querySelector(s);
        if (!e) { out.boxes[s] = null; continue; }
        const b = e.getBoundingClientRect();
        out.boxes[s] = { left: b.left, top: b.top, right: b.right, bottom: b.bottom,
                         width: b.width, height: b.height };
      }
      return out;
    }, selectors);
    const bad = [];
    for (const s of selectors) {
      const b = r.boxes[s];
      if (!b) { bad.push(`${s} is missing`); continue; }
      if (b.width <= 0 || b.height <= 0) bad.push(`${s} has zero size`);
      const eps = 0.5;
      if (b.left < -eps || b.top < -eps || b.right > r.vw + eps || b.bottom > r.vh + eps) {
        bad.push(`${s} at [${b.left.toFixed(1)}, ${b.top.toFixed(1)}]-[${b.right.toFixed(1)}, ` +
                 `${b.bottom.toFixed(1)}] is outside the ${r.vw}x${r.vh} viewport`);
      }
    }
    if (!allowScroll && (r.sw > r.vw || r.sh > r.vh))
      bad.push(`the document (${r.sw}x${r.sh}) is larger than the ${r.vw}x${r.vh} viewport`);
    if (bad.length) throw new CheckFailed(`${this.describe()}: ${bad.join("; ")}`);
    return r;
  }

  /**
   * A PNG screenshot of the viewport, or of the element `selector` (clipped to it); saved to
   * `file` when given. Returns {png (Buffer), width, height, pixels (RGBA Buffer)}.
   */
  async screenshot({ file = null, selector = null } = {}) {
    let buf;
    if (selector) {
      const el = await this.page.$(selector);
      if (!el) throw new CheckFailed(`${this.describe()}: no element matches ${selector}`);
      buf = Buffer.from(await el.screenshot({ type: "png" }));
    } else {
      buf = Buffer.from(await this.page.screenshot({ type: "png" }));
    }
    if (file) fs.writeFileSync(file, buf);
    const { PNG } = require("pngjs");
    const img = PNG.sync.read(buf);
    return { png: buf, width: img.width, height: img.height, pixels: img.data };
  }

  /**
   * Takes a screenshot (of `selector` if given) and fails unless something is drawn in it:
   * at least `minForeground` of its pixels differ from its most common colour (the
   * background) by more than `tolerance` in some channel, and it has at least `minColours`
   * distinct colours (quantised to 5 bits a channel so anti-aliasing noise of one colour
   * does not count many times). Returns the statistics. Defaults and their reasons:
   * tests/web/README.md.
   */
  async checkNotBlank({ selector = null, file = null, minForeground = 0.05, minColours = 8,
                        tolerance = 24 } = {}) {
    const shot = await this.screenshot({ file, selector });
    const s = imageStats(shot.pixels, shot.width, shot.height, tolerance);
    if (s.foreground < minForeground || s.colours < minColours) {
      throw new CheckFailed(
        `${this.describe()}: the screenshot${selector ? " of " + selector : ""} looks blank: ` +
        `${(100 * s.foreground).toFixed(2)}% of ${shot.width}x${shot.height} pixels differ from ` +
        `the background ${s.background} (need ${(100 * minForeground).toFixed(2)}%), ` +
        `${s.colours} colours (need ${minColours})` + (file ? `; saved to ${file}` : ""));
    }
    return s;
  }

  close() {
    return this.page.close();
  }
}

/** Background (most common colour), foreground fraction and distinct colour count of RGBA pixels. */
function imageStats(rgba, width, height, tolerance = 24) {
  const counts = new Map();
  const n = width * height;
  for (let i = 0; i < n; ++i) {
    const r = rgba[4 * i], g = rgba[4 * i + 1], b = rgba[4 * i + 2];
    const q = ((r >> 3) << 10) | ((g >> 3) << 5) | (b >> 3);
    counts.set(q, (counts.get(q) || 0) + 1);
  }
  let bgKey = 0, bgCount = -1;
  for (const [k, c] of counts) if (c > bgCount) { bgKey = k; bgCount = c; }
  // The background's exact colour: the first pixel that quantises to the commonest bucket.
  let br = 0, bgc = 0, bb = 0;
  for (let i = 0; i < n; ++i) {
    const r = rgba[4 * i], g = rgba[4 * i + 1], b = rgba[4 * i + 2];
    if ((((r >> 3) << 10) | ((g >> 3) << 5) | (b >> 3)) === bgKey) { br = r; bgc = g; bb = b; break; }
  }
  let fg = 0;
  for (let i = 0; i < n; ++i) {
    if (Math.abs(rgba[4 * i] - br) > tolerance || Math.abs(rgba[4 * i + 1] - bgc) > tolerance ||
        Math.abs(rgba[4 * i + 2] - bb) > tolerance) ++fg;
  }
  const hex = (v) => v.toString(16).padStart(2, "0");
  return { background: "#" + hex(br) + hex(bgc) + hex(bb), foreground: n ? fg / n : 0,
           colours: counts.size, width, height };
}

/**
 * Runs `body(browser)` for each browser in `names`, launching each once; a browser that is
 * not available is reported and skipped. Returns the names that ran. Throws the first
 * failure after closing the browser.
 */
async function eachBrowser(names, body, log = console.log) {
  const ran = [];
  for (const name of names) {
    if (!available(name)) {
      log(`SKIP ${name}: ${whyUnavailable(name)}`);
      continue;
    }
    const t0 = Date.now();
    const b = await launch(name);
    try {
      log(`${name}: ${await b.version()}`);
      await body(b);
    } finally {
      await b.close();
    }
    log(`${name}: passed in ${Date.now() - t0} ms`);
    ran.push(name);
  }
  return ran;
}

function whyUnavailable(name) {
  try {
    loadPuppeteer();
    executable(name);
    return "";
  } catch (e) {
    return e.message;
  }
}

/** A fresh temporary folder for screenshots and such. */
function tempDir(tag = "pinsim-web") {
  return fs.mkdtempSync(path.join(os.tmpdir(), tag + "-"));
}

module.exports = { SKIP, Unavailable, CheckFailed, launch, available, whyUnavailable, executable,
                   eachBrowser, imageStats, tempDir, sleep };

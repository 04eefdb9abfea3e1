#!/usr/bin/env node
// Command-line page check on top of harness.js (usage: tests/web/README.md, or --help).
// Exit 0: every check passed in every available browser; 1: a check failed; 2: bad usage;
// 77 (ctest's SKIP_RETURN_CODE): puppeteer-core or the first browser is not installed.
"use strict";

const path = require("path");
const h = require("./harness");

const USAGE = `usage: cli.js PAGE [options] [actions...]
options:
  --browser LIST      comma-separated: chromium,firefox (default chromium). The first one
                      must be installed (else exit 77, a skip); later ones are skipped with
                      a message when absent.
  --size WxH          window size in CSS pixels; repeat for several (default 1280x900)
  --dpr N             device pixel ratio (default 1)
  --query STR         appended to the page's file URL, e.g. "?t=0.5"
  --shots DIR         save each not-blank screenshot there as BROWSER-WxH-N.png
actions, run in order on each page (after its load event), then a final error check:
  --wait COND         wait (10 s) until a body data- attribute meets COND: name=value,
                      name!=value, name~regex, name>num, name>=num, name<num, name<=num
                      (name as in dataset: data-state-hash is stateHash)
  --advances NAME     read the numeric data-NAME, then wait until it grows
  --keys SCRIPT       comma-separated: KEY (press 50 ms), KEY:MS (hold MS ms), down:KEY,
                      up:KEY, wait:MS; KEY is a puppeteer key name (Space, ArrowLeft, KeyZ)
  --sleep MS          wait MS milliseconds
  --in-viewport SELS  comma-separated selectors: each wholly inside the viewport, no scrolling
  --not-blank [SEL]   screenshot (of SEL, else the viewport) is not blank (harness defaults)
  --print             print the body's data- attributes`;

function fail(msg, code = 2) {
  console.error("cli.js: " + msg);
  process.exit(code);
}

function parseCondition(text) {
  const m = /^([A-Za-z0-9_]+)(!=|>=|<=|=|~|>|<)(.*)$/.exec(text);
  if (!m) fail(`--wait "${text}": expected name=value, name>num, ... (see --help)`);
  const [, name, op, rhs] = m;
  const num = Number(rhs);
  if ("<>".includes(op[0]) && !Number.isFinite(num)) fail(`--wait "${text}": ${rhs} is not a number`);
  const re = op === "~" ? new RegExp(rhs) : null;
  const test = (d) => {
    const v = d[name];
    if (v === undefined) return false;
    switch (op) {
      case "=": return v === rhs;
      case "!=": return v !== rhs;
      case "~": return re.test(v);
      case ">": return Number(v) > num;
      case ">=": return Number(v) >= num;
      case "<": return Number(v) < num;
      default: return Number(v) <= num;
    }
  };
  return { test, what: `data ${text}` };
}

function parseKeys(text) {
  return text.split(",").filter((s) => s).map((tok) => {
    const [a, b] = tok.split(":");
    if (a === "wait") return { wait: Number(b) };
    if (a === "down") return { key: b, down: 0 };
    if (a === "up") return { key: b, up: 0 };
    return { key: a, hold: b === undefined ? 50 : Number(b) };
  });
}

function parseArgs(argv) {
  const o = { page: null, browsers: ["chromium"], sizes: [], dpr: 1, query: "", shots: null, actions: [] };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    const next = () => {
      if (i + 1 >= argv.length) fail(`${a} needs a value`);
      return argv[++i];
    };
    if (a === "--help" || a === "-h") { console.log(USAGE); process.exit(0); }
    else if (a === "--browser") o.browsers = next().split(",");
    else if (a === "--size") {
      const m = /^(\d+)x(\d+)$/.exec(next());
      if (!m) fail(`--size: expected WxH, e.g. 1280x900`);
      o.sizes.push([Number(m[1]), Number(m[2])]);
    } else if (a === "--dpr") o.dpr = Number(next());
    else if (a === "--query") o.query = next();
    else if (a === "--shots") o.shots = next();
    else if (a === "--wait") o.actions.push({ kind: "wait", cond: parseCondition(next()) });
    else if (a === "--advances") o.actions.push({ kind: "advances", name: next() });
    else if (a === "--keys") o.actions.push({ kind: "keys", script: parseKeys(next()) });
    else if (a === "--sleep") o.actions.push({ kind: "sleep", ms: Number(next()) });
    else if (a === "--in-viewport") o.actions.push({ kind: "viewport", sels: next().split(",") });
    else if (a === "--not-blank") {
      const sel = i + 1 < argv.length && !argv[i + 1].startsWith("--") ? argv[++i] : null;
      o.actions.push({ kind: "blank", sel });
    } else if (a === "--print") o.actions.push({ kind: "print" });
    else if (a.startsWith("--")) fail(`unknown option ${a}\n${USAGE}`);
    else if (o.page === null) o.page = a;
    else fail(`unexpected argument ${a}`);
  }
  if (o.page === null) fail(`no page given\n${USAGE}`);
  for (const b of o.browsers) if (!["chromium", "firefox"].includes(b)) fail(`--browser: unknown ${b}`);
  if (o.sizes.length === 0) o.sizes.push([1280, 900]);
  return o;
}

async function runPage(browser, o, width, height, shotNo) {
  const page = await browser.open(o.page, { width, height, dpr: o.dpr, query: o.query });
  const tag = `${browser.name} ${width}x${height}`;
  try {
    for (const a of o.actions) {
      if (a.kind === "wait") {
        await page.waitForData(a.cond.test, { what: a.cond.what });
      } else if (a.kind === "advances") {
        const v0 = Number((await page.data())[a.name]);
        if (!Number.isFinite(v0)) throw new h.CheckFailed(`${tag}: data ${a.name} is not a number`);
        const d = await page.waitForData((d) => Number(d[a.name]) > v0, { what: `${a.name} > ${v0}` });
        console.log(`${tag}: ${a.name} advanced ${v0} -> ${d[a.name]}`);
      } else if (a.kind === "keys") {
        for (const k of a.script) {
          if (k.hold !== undefined) await page.press(k.key, k.hold);
          else await page.keys([k]);
        }
      } else if (a.kind === "sleep") {
        await page.sleep(a.ms);
      } else if (a.kind === "viewport") {
        await page.checkInViewport(a.sels);
        console.log(`${tag}: in the viewport: ${a.sels.join(" ")}`);
      } else if (a.kind === "blank") {
        const file = o.shots ? path.join(o.shots, `${browser.name}-${width}x${height}-${++shotNo.n}.png`) : null;
        const s = await page.checkNotBlank({ selector: a.sel, file });
        console.log(`${tag}: not blank${a.sel ? " (" + a.sel + ")" : ""}: ${s.width}x${s.height}, ` +
                    `${(100 * s.foreground).toFixed(1)}% foreground on ${s.background}, ${s.colours} colours`);
      } else if (a.kind === "print") {
        console.log(`${tag}: ${JSON.stringify(await page.data())}`);
      }
    }
    await page.checkErrors();
  } finally {
    await page.close();
  }
}

async function main() {
  const o = parseArgs(process.argv.slice(2));
  if (!h.available(o.browsers[0])) {
    console.log(`SKIPPED: ${h.whyUnavailable(o.browsers[0])}`);
    process.exit(h.SKIP);
  }
  if (o.shots) require("fs").mkdirSync(o.shots, { recursive: true });
  const shotNo = { n: 0 };
  await h.eachBrowser(o.browsers, async (b) => {
    for (const [w, hgt] of o.sizes) await runPage(b, o, w, hgt, shotNo);
  });
  console.log("cli.js: all checks passed");
}

main().catch((e) => {
  console.error("FAILED: " + (e && e.message ? e.message : e));
  process.exit(1);
});

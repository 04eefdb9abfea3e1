// The web engine (pinsim_web.js, WebAssembly) against the native pinsim, in node: the same
// recording gives the same state hash both ways (issue 17, bit-identity).
//  1. page -> native: a game played through the wasm engine (a seeded schedule of plunger and
//     flipper presses) is saved as a recording; `pinsim play --rerun` reruns it natively and
//     must report the identical state hash (it recomputes it from the physics).
//  2. native -> page: `pinsim play --script ... --record` (SDL's dummy video driver, no
//     window) records a game natively; the wasm engine reruns it and must reach the hash
//     and score the native run wrote.
//  3. both builds compile every file with -ffp-contract=off and without fast-math (their
//     compile_commands.json).
// Usage: node engine_node.js --pinsim BIN --engine pinsim_web.js --scene S --tmp DIR
//        [--native-build DIR --web-build DIR]
"use strict";
const fs = require("fs");
const path = require("path");
const { execFileSync, spawnSync } = require("child_process");

function arg(name, def) {
  const i = process.argv.indexOf("--" + name);
  return i >= 0 ? process.argv[i + 1] : def;
}
const pinsim = arg("pinsim"), enginePath = arg("engine"), scene = arg("scene");
const tmp = arg("tmp", fs.mkdtempSync("/tmp/pinsim-share-"));
fs.mkdirSync(tmp, { recursive: true });
let failures = 0;
function check(ok, what) {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failures++;
}
if (!fs.existsSync(enginePath)) {
  console.log("SKIPPED: " + enginePath + " is not built (cmake --preset web && cmake --build --preset web)");
  process.exit(77);
}

// A small deterministic generator (mulberry32), so the schedule is the same every run.
function rng(seed) {
  return () => {
    seed = (seed + 0x6d2b79f5) | 0;
    let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

function checkFlags(dir, label) {
  const f = path.join(dir, "compile_commands.json");
  if (!fs.existsSync(f)) return check(false, label + ": " + f + " exists");
  const cmds = JSON.parse(fs.readFileSync(f, "utf8"));
  // The engine's files (tests/fixtures holds deliberately broken plugin libraries).
  const engine = cmds.filter((c) => /\/(framework|backends|plugins)\//.test(c.file) && !/\/tests\//.test(c.file));
  const bad = engine.filter((c) => !c.command.includes("-ffp-contract=off") ||
                                 /-ffast-math|-Ofast|-funsafe-math/.test(c.command));
  check(engine.length > 20 && bad.length === 0,
        `${label}: all ${engine.length} engine compile commands have -ffp-contract=off, no fast-math` +
        (bad.length ? " (not: " + bad.slice(0, 3).map((c) => c.file).join(", ") + ")" : ""));
}

require(path.resolve(enginePath))().then((m) => {
  const api = {
    load: m.cwrap("pinsim_web_load", "number", ["string", "string"]),
    error: m.cwrap("pinsim_web_error", "string", []),
    setInput: m.cwrap("pinsim_web_set_input", "number", ["string", "number"]),
    step: m.cwrap("pinsim_web_step", "number", ["number"]),
    dt: m.cwrap("pinsim_web_dt", "number", []),
    status: m.cwrap("pinsim_web_status", "string", []),
    recording: m.cwrap("pinsim_web_recording", "string", []),
    inputs: m.cwrap("pinsim_web_inputs", "string", []),
    rerun: m.cwrap("pinsim_web_rerun", "number", ["string"]),
  };
  const ok = (rc) => { if (rc !== 0) throw new Error(api.error()); };
  ok(api.load(fs.readFileSync(scene, "utf8"), scene));

  // 1. page -> native. Frames of 1/60 s as the page steps; presses between frames.
  const dt = api.dt(), perFrame = Math.round(1 / 60 / dt), r = rng(17);
  ok(api.setInput("plunger", 1));
  ok(api.step(perFrame * 36));  // pull 0.6 s
  ok(api.setInput("plunger", 0));
  // The flippers: the inputs other than the plunger (pinball.json: "left", "right").
  const flippers = JSON.parse(api.inputs()).filter((n) => n !== "plunger");
  check(flippers.length === 2, "the scene has two flipper inputs: " + flippers.join(", "));
  const held = Object.fromEntries(flippers.map((n) => [n, false]));
  for (let frame = 0; frame < 60 * 12; ++frame) {
    for (const name of Object.keys(held))
      if (r() < 0.08) { held[name] = !held[name]; ok(api.setInput(name, held[name] ? 1 : 0)); }
    ok(api.step(perFrame));
  }
  const pageStatus = JSON.parse(api.status());
  const recFile = path.join(tmp, "page_recording.json");
  fs.writeFileSync(recFile, api.recording());
  const rec = JSON.parse(fs.readFileSync(recFile, "utf8"));
  check(rec.inputs.length > 10 && rec.steps === pageStatus.steps,
        `page recording: ${rec.inputs.length} inputs, ${rec.steps} steps, score ${rec.score}, hash ${rec.state_hash}`);
  const native = spawnSync(pinsim, ["-q", "play", scene, "--rerun", recFile], { encoding: "utf8" });
  process.stdout.write("  native: " + native.stdout + native.stderr);
  check(native.status === 0 && native.stdout.includes(rec.state_hash + " ") &&
        native.stdout.includes("identical"),
        "pinsim play --rerun of the page's recording reaches the same state hash");

  // 2. native -> page.
  const script = [{ t: 0.05, input: "plunger", action: "press" },
                  { t: 0.65, input: "plunger", action: "release" }];
  for (let k = 0, t = 1.0; t < 7.0; ++k, t += 0.37)
    script.push({ t: +t.toFixed(3), input: flippers[k % 2], action: "press" },
                { t: +(t + 0.15).toFixed(3), input: flippers[k % 2], action: "release" });
  const scriptFile = path.join(tmp, "script.json"), nativeRec = path.join(tmp, "native_recording.json");
  fs.writeFileSync(scriptFile, JSON.stringify(script));
  const play = spawnSync(pinsim, ["-q", "play", scene, "--script", scriptFile, "--seconds", "7.5",
                                  "--record", nativeRec],
                         { encoding: "utf8", env: { ...process.env, SDL_VIDEODRIVER: "dummy" } });
  check(play.status === 0 && fs.existsSync(nativeRec),
        "pinsim play --script --record (SDL dummy driver) wrote a recording" +
        (play.status === 0 ? "" : ": " + play.stderr));
  if (fs.existsSync(nativeRec)) {
    const nrec = JSON.parse(fs.readFileSync(nativeRec, "utf8"));
    ok(api.rerun(JSON.stringify(nrec)));
    const s = JSON.parse(api.status());
    check(nrec.inputs.length === script.length, `native recording: ${nrec.inputs.length} inputs`);
    check(s.state_hash === nrec.state_hash && s.score === nrec.score && s.steps === nrec.steps,
          `the engine's rerun of the native recording: hash ${s.state_hash} (native ${nrec.state_hash}), ` +
          `score ${s.score} (native ${nrec.score}), steps ${s.steps} (native ${nrec.steps})`);
  }

  // 2b. Recordings the page's "load" button may be given (any file): refused at once with
  // the JSON path, never rerun wrong (an unknown input skipped, inputs applied late) nor
  // for ever (an edited step count of 1e18: the ball rests in the plunger lane).
  const base = { scene: "pinball.json", steps: 10, state_hash: "0",
                 inputs: [{ step: 0, input: flippers[0], action: "press" }] };
  const bad = [
    [(j) => { j.steps = 1e18; }, "recording: steps: 1000000000000000000 steps of dt = 0.0002 s"],
    [(j) => { j.inputs[0].input = "lefft"; }, "recording: inputs[0].input: unknown input 'lefft'"],
    [(j) => { j.inputs[0].step = 11; }, "recording: inputs[0].step: step 11 is after the recording's 10 steps"],
    [(j) => { j.inputs[0].step = 5; j.inputs.push({ step: 4, input: flippers[0], action: "release" }); },
     "recording: inputs[1].step: step 4 comes before the previous input's 5"],
    [(j) => { j.inputs[0].action = "hold"; }, "recording: inputs[0].action: expected \"press\" or \"release\""],
    [(j) => { j.inputs = 3; }, "recording: inputs: expected a list of inputs"],
    [(j) => { delete j.steps; }, "recording: steps: required step count"],
    [(j) => { j.steps = "10"; }, "recording: steps: expected a non-negative integer"],
    [(j) => { j.steps = 1.5; }, "recording: steps: expected a non-negative integer"],
    // 2 hours of play: more than the page reruns (an hour), though the CLI would (a day)
    [(j) => { j.steps = 36000000; }, "more than the limit of 3600 s"],
  ];
  // Nested 100,000 deep: refused while parsing (nothing recursive meets it), the engine alive.
  {
    const deep = '{"steps": 10, "inputs": ' + "[".repeat(100000) + "]".repeat(100000) + "}";
    const rc = api.rerun(deep);
    const err = rc === 0 ? "" : api.error();
    check(rc !== 0 && err.includes("nested deeper than"),
          "the engine refuses a recording nested 100,000 deep: " + (err || "accepted"));
    ok(api.rerun(JSON.stringify(base)));  // and still reruns a good one afterwards
  }
  for (const [change, message] of bad) {
    const j = JSON.parse(JSON.stringify(base));
    change(j);
    const t0 = Date.now();
    const rc = api.rerun(JSON.stringify(j));
    const err = rc === 0 ? "" : api.error();
    check(rc !== 0 && err.includes(message) && Date.now() - t0 < 5000,
          `the engine refuses a bad recording (${message.slice(0, 40)}...): ` + (err || "accepted"));
  }

  // 3. floating-point flags.
  if (arg("native-build")) checkFlags(arg("native-build"), "native build");
  if (arg("web-build")) checkFlags(arg("web-build"), "web build");
  process.exit(failures ? 1 : 0);
}).catch((e) => { console.log("FAIL " + (e.stack || e)); process.exit(1); });

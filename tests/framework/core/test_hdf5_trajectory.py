#!/usr/bin/env python3
"""trajectory.h5 (scene "output": {"format": "hdf5"}) against trajectory.csv, end to end.

1. A finished run: every frame of the HDF5 file holds the same doubles (same bits) as the
   CSV run of the same scene (the CSV prints the shortest decimal that reads back as the
   same double, so float() of its text is exact); h5dump reads the file; render (SVG and
   PNG) and replay produce the same bytes from the CSV and the HDF5 run folders.
2. kill -9 in the middle of runs (three moments): the file opens with h5py and h5dump,
   frames_complete > 0, and the first frames_complete frames equal a CSV run's values
   (the CSV run stops at the same time); `pinsim render` reads the killed folder.
3. output.format "xml": exit 2 and a message naming output.format.
4. The frames are written on a writer thread; the file does not depend on its timing: two
   runs of the same scene give the same bytes.
5. SIGINT and SIGTERM: the queued frames are written before summary.json says
   "interrupted": frames_complete is the summary's steps + 1 (every step's frame and the
   initial one).
6. A file-size limit (RLIMIT_FSIZE) and, as root, a full disk (a 1 MiB tmpfs): exit 1, a
   message naming trajectory.h5 and the reason, summary.json's error of kind "output", and a
   file that h5py and h5dump open whose first frames_complete frames equal a CSV run's.
7. /radius, /mass (inf where pinned) and /pinned hold the scene's particles.
8. output.compression: deflate at that level, the same doubles; bad levels are exit 2.

Usage: test_hdf5_trajectory.py PINSIM_BIN WORK_DIR
"""
import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np

PINSIM, WORK = sys.argv[1], sys.argv[2]
shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)

SCENE = {
    "name": "h5_chain",
    "time": {"dt": 0.001, "duration": 0.2},
    "integrator": "symplectic_euler",
    "backend": {"name": "sdf"},
    "bodies": [{"type": "strand", "name": "chain", "root": [0, 1], "direction": [1, 0],
                "count": 12, "segment_length": 0.1, "mass": 0.1, "pin": [0]}],
    "forces": [{"type": "gravity"},
               {"type": "damped_spring", "params": {"ks": 500, "kd": 0.5},
                "elements": {"body": "chain", "set": "edges"}}],
    "obstacles": [{"id": "floor",
                   "shape": {"type": "box", "center": [0, -0.5], "half_size": [4, 0.5]}}],
    "output": {"every": 2},
}
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


def run(*args, **kw):
    return subprocess.run([PINSIM, *args], capture_output=True, text=True, **kw)


def write_scene(name, scene):
    path = os.path.join(WORK, name)
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def csv_frames(folder):
    """{t: {particle: (x, y, vx, vy)}} from trajectory.csv, exact doubles."""
    frames = {}
    with open(os.path.join(folder, "trajectory.csv")) as f:
        for row in csv.DictReader(f):
            frames.setdefault(float(row["t"]), {})[int(row["particle"])] = tuple(
                float(row[k]) for k in ("x", "y", "vx", "vy"))
    return frames


def compare(h5file, csv_folder, frames):
    """The first `frames` frames of h5file against the CSV run's, bit for bit."""
    ref = csv_frames(csv_folder)
    times = sorted(ref)
    with h5py.File(h5file, "r") as f:
        t = f["t"][:frames]
        cols = [f[k][:frames, :] for k in ("x", "y", "vx", "vy")]
    check(len(times) >= frames, f"{csv_folder}: {len(times)} CSV frames < {frames}")
    for i in range(min(frames, len(times))):
        check(t[i] == times[i], f"frame {i}: t {t[i]!r} != CSV {times[i]!r}")
        for p, vals in ref[times[i]].items():
            got = tuple(c[i, p] for c in cols)
            if got != vals:
                check(False, f"frame {i} particle {p}: {got} != CSV {vals}")
                return


# 1. Finished runs.
# One scene file for both (replay embeds summary.json, which names it); HDF5 by --set.
scene = write_scene("chain.json", SCENE)
csv_dir, h5_dir = os.path.join(WORK, "csv", "run"), os.path.join(WORK, "h5", "run")
for out, extra in ((csv_dir, []), (h5_dir, ["--set", "output.format=hdf5"])):
    r = run("-q", "run", scene, "--out", out, *extra)
    check(r.returncode == 0, f"run {out}: exit {r.returncode}: {r.stderr}")
h5file = os.path.join(h5_dir, "trajectory.h5")
check(os.path.exists(h5file) and not os.path.exists(os.path.join(h5_dir, "trajectory.csv")),
      "the hdf5 run writes trajectory.h5 and no trajectory.csv")
with h5py.File(h5file, "r") as f:
    n = int(f.attrs["frames_complete"])
    check(n == 101, f"frames_complete {n}, expected 0.2 / 0.001 / 2 + 1 = 101")
    check(f["x"].shape == (n, 12) and f["t"].shape == (n,), f"shapes {f['x'].shape}")
    check(f["x"].dtype == np.float64, "float64 datasets")
    check(int(f.attrs["particles"]) == 12, "particles attribute")
    check(float(f.attrs["dt"]) == 0.001, "dt attribute")
    check(f.attrs["scene"] in (b"h5_chain", "h5_chain"), f"scene attribute {f.attrs['scene']}")
compare(h5file, csv_dir, 101)
d = subprocess.run(["h5dump", "-d", "/x", h5file], capture_output=True, text=True)
check(d.returncode == 0 and "DATASPACE  SIMPLE { ( 101, 12 )" in d.stdout,
      f"h5dump /x: exit {d.returncode} {d.stdout[:300]} {d.stderr[:300]}")
for kind, args in (("render svg", ["render", "{dir}", "--out", "{out}.svg"]),
                   ("render png", ["render", "{dir}", "--out", "{out}.png"]),
                   ("replay", ["replay", "{dir}", "--out", "{out}.html"])):
    outs = []
    for label, folder in (("csv", csv_dir), ("h5", h5_dir)):
        stem = os.path.join(WORK, f"{label}_{kind.replace(' ', '_')}")
        r = run("-q", *[a.format(dir=folder, out=stem) for a in args])
        check(r.returncode == 0, f"{kind} {label}: exit {r.returncode}: {r.stderr}")
        ext = args[-1].rsplit(".", 1)[1]
        page = open(f"{stem}.{ext}", "rb").read() if r.returncode == 0 else b""
        # The replay page embeds summary.json: all equal but the runs' wall and CPU times.
        outs.append(re.sub(rb'"(wall|cpu)_time_s":[0-9.e+-]+', b"", page))
    check(outs[0] == outs[1] and len(outs[0]) > 1000,
          f"{kind}: the CSV and HDF5 run folders give different output")

# 2. kill -9 mid-run (a long run, every step written), at three moments. The moments are set
# by the file's size (12 particles x 4 doubles + t: ~400 bytes a frame), not by wall time, so a
# loaded machine that starts the run late still kills it mid-write: at ~15,000, ~40,000 and
# ~60,000 frames, then 1-3 ms more so the kill lands at different points within a frame.
long_scene = dict(SCENE, time={"dt": 0.0001, "duration": 1000.0},
                  output={"every": 1, "format": "hdf5"})
long_path = write_scene("long.json", long_scene)


def start_until_size(scene_path, out, size):
    """Starts `pinsim run` on scene_path into out and returns once its trajectory.h5 holds
    `size` bytes (or the run ended, or 120 s passed); the process is still running."""
    f5 = os.path.join(out, "trajectory.h5")
    p = subprocess.Popen([PINSIM, "-q", "run", scene_path, "--out", out],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline and p.poll() is None:
        if os.path.exists(f5) and os.path.getsize(f5) >= size:
            break
        time.sleep(0.01)
    return p

for k, size in enumerate((6_000_000, 16_000_000, 24_000_000)):
    out = os.path.join(WORK, f"killed{k}")
    f5 = os.path.join(out, "trajectory.h5")
    p = start_until_size(long_path, out, size)
    time.sleep(0.001 * (k + 1))
    p.send_signal(signal.SIGKILL)
    p.wait()
    d = subprocess.run(["h5dump", "-A", f5], capture_output=True, text=True)
    check(d.returncode == 0 and "frames_complete" in d.stdout,
          f"kill {k}: h5dump -A: exit {d.returncode}: {d.stderr[:300]}")
    try:
        with h5py.File(f5, "r") as f:
            n = int(f.attrs["frames_complete"])
            shapes = [f[c].shape[0] for c in ("t", "x", "y", "vx", "vy")]
    except OSError as e:
        check(False, f"kill {k}: h5py cannot open the file: {e}")
        continue
    print(f"kill {k} at {size} bytes: frames_complete {n}, dataset frames {shapes}")
    check(n > 10 and all(s >= n for s in shapes), f"kill {k}: frames {n} / {shapes}")
    # The same scene as CSV, stopped after frame n - 1 (t = (n - 1) dt).
    ref = os.path.join(WORK, f"killed{k}_csv")
    r = run("-q", "run", long_path, "--out", ref, "--set", "output.format=csv",
            "--set", f"time.duration={(n - 1) * 0.0001!r}")
    check(r.returncode == 0, f"kill {k}: csv run: {r.stderr}")
    compare(f5, ref, n)
    r = run("-q", "render", out, "--out", os.path.join(WORK, f"killed{k}.png"))
    check(r.returncode == 0, f"kill {k}: render of the killed run: {r.stderr}")

# 3. A bad format.
bad = write_scene("bad.json", dict(SCENE, output={"format": "xml"}))
r = run("-q", "run", bad, "--out", os.path.join(WORK, "bad"))
check(r.returncode == 2 and "output.format" in r.stderr and "hdf5" in r.stderr,
      f"bad format: exit {r.returncode}: {r.stderr}")

# 4. The same bytes for the same run.
again = os.path.join(WORK, "h5", "again")
r = run("-q", "run", scene, "--out", again, "--set", "output.format=hdf5")
check(r.returncode == 0, f"second hdf5 run: exit {r.returncode}: {r.stderr}")
if r.returncode == 0:
    check(open(h5file, "rb").read() == open(os.path.join(again, "trajectory.h5"), "rb").read(),
          "two runs of the same scene write different trajectory.h5 bytes")

# 5. SIGINT / SIGTERM: the writer's queue is drained before the summary is written.
for sig in (signal.SIGINT, signal.SIGTERM):
    out = os.path.join(WORK, f"stopped_{sig.name}")
    f5 = os.path.join(out, "trajectory.h5")
    p = start_until_size(long_path, out, 3_000_000)
    p.send_signal(sig)
    p.wait(timeout=60)
    s = json.load(open(os.path.join(out, "summary.json")))
    check(s["status"] == "interrupted", f"{sig.name}: status {s['status']}")
    with h5py.File(f5, "r") as f:
        n = int(f.attrs["frames_complete"])
        last_t = float(f["t"][n - 1]) if n else None
    print(f"{sig.name}: steps {s['steps']}, frames_complete {n}")
    check(n == s["steps"] + 1 and n > 1000,
          f"{sig.name}: frames_complete {n}, summary steps {s['steps']} (expected steps + 1)")
    check(last_t == s["t_end"], f"{sig.name}: last frame's t {last_t} != t_end {s['t_end']}")


def check_failed_run(label, r, out, reason):
    """A run that could not write: exit 1 naming the file and `reason`, whole frames kept."""
    f5 = os.path.join(out, "trajectory.h5")
    check(r.returncode == 1, f"{label}: exit {r.returncode}: {r.stderr[-500:]}")
    check(f5 + ": cannot write frame" in r.stderr and reason in r.stderr,
          f"{label}: message: {r.stderr[-500:]}")
    s = json.load(open(os.path.join(out, "summary.json")))
    check(s["status"] == "error" and s["error"]["kind"] == "output" and
          "trajectory.h5" in s["error"]["message"], f"{label}: summary {s.get('error')}")
    d = subprocess.run(["h5dump", "-A", f5], capture_output=True, text=True)
    check(d.returncode == 0, f"{label}: h5dump -A: {d.stderr[:300]}")
    try:
        with h5py.File(f5, "r") as f:
            n = int(f.attrs["frames_complete"])
    except OSError as e:
        check(False, f"{label}: h5py cannot open the file: {e}")
        return
    print(f"{label}: frames_complete {n}, file {os.path.getsize(f5)} bytes")
    check(n > 100, f"{label}: frames_complete {n}")
    ref = os.path.join(WORK, f"{label}_csv")
    r = run("-q", "run", long_path, "--out", ref, "--set", "output.format=csv",
            "--set", f"time.duration={(n - 1) * 0.0001!r}")
    check(r.returncode == 0, f"{label}: csv run: {r.stderr}")
    compare(f5, ref, n)


# 6. A file-size limit; a full disk.
out = os.path.join(WORK, "fsize")
r = subprocess.run(["prlimit", "--fsize=3000000", PINSIM, "-q", "run", long_path, "--out", out],
                   capture_output=True, text=True)
check_failed_run("fsize", r, out, "File too large")
check(os.path.getsize(os.path.join(out, "trajectory.h5")) <= 3000000, "fsize: file over the limit")
if os.geteuid() == 0:
    mnt, copy = os.path.join(WORK, "mnt"), os.path.join(WORK, "full")
    os.makedirs(mnt)
    os.makedirs(copy)
    script = (f"mount -t tmpfs -o size=1m tmpfs {mnt} || exit 99; "
              f"{PINSIM} -q run {long_path} --out {mnt}/run; echo rc=$? >&2; "
              f"cp {mnt}/run/* {copy}")
    r = subprocess.run(["unshare", "--mount", "sh", "-c", script], capture_output=True, text=True)
    if "rc=" not in r.stderr:
        print("full disk: cannot mount a tmpfs here, skipped:", r.stderr[-300:])
    else:
        r.returncode = int(r.stderr.rsplit("rc=", 1)[1].split()[0])
        # The message names the file inside the tmpfs; the copy is checked.
        r.stderr = r.stderr.replace(f"{mnt}/run", copy)
        check_failed_run("full", r, copy, "No space left on device")
else:
    print("full disk: not root, skipped (the file-size limit covers the same path)")

# 7. The particles' constant properties: /radius, /mass (inf where pinned), /pinned, exactly
# as the scene gives them.
props = write_scene("props.json", {
    "name": "h5_props", "time": {"dt": 0.01, "duration": 0.05}, "backend": {"name": "none"},
    "particles": [{"x": [0, 0], "mass": 2.5, "radius": 0.05},
                  {"x": [1, 0], "pinned": True, "radius": 0.125},
                  {"x": [2, 0], "mass": 0.75, "radius": 0.2}],
    "forces": [{"type": "gravity"}], "output": {"format": "hdf5"}})
out = os.path.join(WORK, "props")
r = run("-q", "run", props, "--out", out)
check(r.returncode == 0, f"props run: exit {r.returncode}: {r.stderr}")
with h5py.File(os.path.join(out, "trajectory.h5"), "r") as f:
    check(list(f["radius"][:]) == [0.05, 0.125, 0.2], f"radius {f['radius'][:]}")
    check(list(f["mass"][:]) == [2.5, float("inf"), 0.75], f"mass {f['mass'][:]}")
    check(list(f["pinned"][:]) == [0, 1, 0] and f["pinned"].dtype == np.uint8,
          f"pinned {f['pinned'][:]} {f['pinned'].dtype}")
    check(int(f.attrs["compression"]) == 0, "compression attribute 0 by default")

# 8. output.compression: deflate on the frame datasets, the same doubles as without it;
# a level out of 0..9, or compression for a CSV run, is exit 2 naming output.compression.
gz_dir = os.path.join(WORK, "gz", "run")
r = run("-q", "run", scene, "--out", gz_dir, "--set", "output.format=hdf5",
        "--set", "output.compression=6")
check(r.returncode == 0, f"compressed run: exit {r.returncode}: {r.stderr}")
with h5py.File(os.path.join(gz_dir, "trajectory.h5"), "r") as g, h5py.File(h5file, "r") as f:
    check(g["x"].compression == "gzip" and g["x"].compression_opts == 6,
          f"/x filter {g['x'].compression} {g['x'].compression_opts}")
    check(f["x"].compression is None, "the default run is not compressed")
    check(int(g.attrs["compression"]) == 6, "compression attribute")
    for k in ("t", "x", "y", "vx", "vy", "radius", "mass", "pinned"):
        check(np.array_equal(g[k][:], f[k][:]), f"compressed /{k} differs from the plain file")
for sets, what in ((["output.format=hdf5", "output.compression=10"], "from 0 (none) to 9"),
                   (["output.compression=3"], "hdf5\" only")):
    args = [a for kv in sets for a in ("--set", kv)]
    r = run("-q", "run", scene, "--out", os.path.join(WORK, "badgz"), *args)
    check(r.returncode == 2 and "output.compression" in r.stderr and what in r.stderr,
          f"compression {sets}: exit {r.returncode}: {r.stderr}")

shutil.rmtree(WORK, ignore_errors=True) if not failures else None
print("FAILED:" if failures else "ok", *failures, sep="\n")
sys.exit(1 if failures else 0)

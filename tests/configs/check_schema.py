"""Checks configs/scene.schema.json against the shipped scenes and against broken ones, and
configs/bench.schema.json and configs/stress.schema.json against the shipped bench and
stress configs (their embedded scenes through the scene schema) and broken ones.

Usage: check_schema.py CONFIGS_DIR. Exit 0 when every file validates and every
deliberately broken one is rejected; 1 otherwise (each failure printed).
"""
import copy
import glob
import json
import os
import pathlib
import sys

import jsonschema


def strip_comments(text):
    """Removes // and /* */ comments outside strings (scenes are JSON with comments)."""
    out, i, in_string = [], 0, False
    while i < len(text):
        c = text[i]
        if in_string:
            out.append(c)
            if c == "\\":
                out.append(text[i + 1])
                i += 2
                continue
            if c == '"':
                in_string = False
        elif c == '"':
            in_string = True
            out.append(c)
        elif text.startswith("//", i):
            while i < len(text) and text[i] != "\n":
                i += 1
            continue
        elif text.startswith("/*", i):
            i = text.index("*/", i) + 2
            continue
        else:
            out.append(c)
        i += 1
    return "".join(out)


def is_scene(path, data):
    """Scenes have a time block; rubrics, bench and stress configs do not."""
    return isinstance(data, dict) and "time" in data and not path.endswith("scene.schema.json")


def main(configs):
    schema = json.load(open(os.path.join(configs, "scene.schema.json")))
    validator = jsonschema.validators.validator_for(schema)(schema)
    failures, scenes = [], {}
    for path in sorted(glob.glob(os.path.join(configs, "**", "*.json"), recursive=True)):
        data = json.loads(strip_comments(open(path).read()))
        if not is_scene(path, data):
            continue
        scenes[path] = data
        for err in validator.iter_errors(data):
            failures.append(f"{path}: {'/'.join(map(str, err.absolute_path))}: {err.message}")
    if len(scenes) < 10:
        failures.append(f"only {len(scenes)} scenes found under {configs}")

    # Broken variants of a scene with bodies must be rejected.
    base = scenes[os.path.join(configs, "blob_drop.json")]
    broken = {
        "unknown top-level key": lambda s: s.update({"gravty": 1}),
        "unknown body key": lambda s: s["bodies"][0].update({"radiuss": 0.1}),
        "unknown body type": lambda s: s["bodies"][0].update({"type": "torus"}),
        "ring_blob count below 3": lambda s: s["bodies"][0].update({"count": 2}),
        "negative radius": lambda s: s["bodies"][0].update({"radius": -1}),
        "unknown output format": lambda s: s["output"].update({"format": "xml"}),
    }
    for what, change in broken.items():
        scene = copy.deepcopy(base)
        change(scene)
        if validator.is_valid(scene):
            failures.append(f"the schema accepts a scene with an {what}")

    swept, sweep_broken = check_sweeps(configs, schema, failures)
    rubrics, rubric_broken = check_rubrics(configs, failures)
    for f in failures:
        print("FAIL", f)
    print(f"{len(scenes)} scenes validated, {len(broken)} broken scenes checked, "
          f"{swept} bench/stress configs validated, {sweep_broken} broken ones checked, "
          f"{rubrics} rubrics validated, {rubric_broken} broken ones checked, "
          f"{len(failures)} failures")
    return 1 if failures else 0


def sweep_validator(configs, name, scene_schema):
    """A validator for configs/NAME whose "$ref": "scene.schema.json" (relative, as an
    editor resolves it) reaches the scene schema; works with jsonschema 4.10 (Debian
    bookworm, RefResolver) and 4.18+ (referencing)."""
    path = pathlib.Path(configs, name).resolve()
    schema = dict(json.load(open(path)), **{"$id": path.as_uri()})
    scene_uri = path.with_name("scene.schema.json").as_uri()
    cls = jsonschema.validators.validator_for(schema)
    try:
        from referencing import Registry, Resource
        res = Resource.from_contents(scene_schema)
        registry = Registry().with_resources([(scene_uri, res), (scene_schema["$id"], res)])
        return cls(schema, registry=registry)
    except ImportError:
        # (4.10 would take the scene schema's urn "$id" as the base of its "#/definitions"
        # references, which urljoin cannot resolve against: the file URI serves instead)
        scene = {k: v for k, v in scene_schema.items() if k != "$id"}
        store = {scene_uri: scene}
        return cls(schema, resolver=jsonschema.RefResolver.from_schema(schema, store=store))


def check_sweeps(configs, scene_schema, failures):
    validators = {kind: sweep_validator(configs, f"{kind}.schema.json", scene_schema)
                  for kind in ("bench", "stress")}
    docs = {}
    for kind, v in validators.items():
        for path in sorted(glob.glob(os.path.join(configs, kind, "*.json"))):
            data = json.loads(strip_comments(open(path).read()))
            docs[path] = data
            for err in v.iter_errors(data):
                failures.append(f"{path}: {'/'.join(map(str, err.absolute_path))}: {err.message}")
    if len(docs) < 4:
        failures.append(f"only {len(docs)} bench/stress configs found under {configs}")

    bench = docs[os.path.join(configs, "bench", "integrators.json")]
    springs = docs[os.path.join(configs, "stress", "springs.json")]
    tunnel = docs[os.path.join(configs, "stress", "tunnelling.json")]

    def harmonic(d):  # the first case with a harmonic answer
        return next(c for c in d["cases"] if c.get("answer", {}).get("type") == "harmonic")

    broken = [
        ("bench", bench, "an unknown top-level key", lambda d: d.update({"repeat": 3})),
        ("bench", bench, "a misspelt answer key",
         lambda d: harmonic(d)["answer"].update({"damping": 0.1})),
        ("bench", bench, "an unknown answer type",
         lambda d: harmonic(d)["answer"].update({"type": "pendulum"})),
        ("bench", bench, "both an answer and a reference",
         lambda d: harmonic(d).update({"reference": {"dt": 1e-5}})),
        ("bench", bench, "an unknown integrator", lambda d: d.update({"integrators": ["rk5"]})),
        ("bench", bench, "a zero time step", lambda d: harmonic(d).update({"dt": [0.01, 0]})),
        ("bench", bench, "an embedded scene with an unknown key",
         lambda d: harmonic(d)["scene"].update({"gravty": 1})),
        ("stress", springs, "a stiffness case without stiffness",
         lambda d: d["cases"][0].pop("stiffness")),
        ("stress", springs, "a stiffness with an unknown key",
         lambda d: d["cases"][0]["stiffness"].update({"value": [1]})),
        ("stress", tunnel, "a tunnelling case without speeds", lambda d: d["cases"][0].pop("speeds")),
        ("stress", tunnel, "an unknown case kind", lambda d: d["cases"][0].update({"kind": "melt"})),
    ]
    for kind, base, what, change in broken:
        doc = copy.deepcopy(base)
        change(doc)
        if validators[kind].is_valid(doc):
            failures.append(f"the {kind} schema accepts a config with {what}")
    return len(docs), len(broken)


def check_rubrics(configs, failures):
    """configs/grading/rubric.schema.json against the shipped rubrics (and the test suite's
    own, in tests/framework/grading) and against broken ones."""
    schema = json.load(open(os.path.join(configs, "grading", "rubric.schema.json")))
    v = jsonschema.validators.validator_for(schema)(schema)
    tests_dir = os.path.join(configs, "..", "tests", "framework", "grading")
    paths = sorted(glob.glob(os.path.join(configs, "grading", "*.json")) +
                   glob.glob(os.path.join(tests_dir, "rubric_*.json")))
    docs = {}
    for path in paths:
        if path.endswith("schema.json"):
            continue
        data = json.loads(strip_comments(open(path).read()))
        docs[os.path.basename(path)] = data
        for err in v.iter_errors(data):
            failures.append(f"{path}: {'/'.join(map(str, err.absolute_path))}: {err.message}")
    if len(docs) < 3:
        failures.append(f"only {len(docs)} rubrics found")
    force = docs["force_assignment.json"]
    broken = [
        ("an unknown top-level key", lambda d: d.update({"limit": {}})),
        ("an unknown test key", lambda d: d["tests"][0].update({"pionts": 3})),
        ("an unknown check", lambda d: d["tests"][0].update({"check": "energy"})),
        ("an unknown limit", lambda d: d.update({"limits": {"cpu_second": 3}})),
        ("a zero wall-clock limit", lambda d: d.update({"limits": {"wall_seconds": 0}})),
        ("a reference test without a reference",
         lambda d: next(t for t in d["tests"] if t["check"] == "reference").pop("reference")),
        ("a simulation test without a scene",
         lambda d: next(t for t in d["tests"] if t["check"] == "simulation").pop("scene")),
        ("a bad visibility", lambda d: d["tests"][0].update({"visibility": "secret"})),
        ("a bad top-level visibility", lambda d: d.update({"visibility": "later"})),
        ("a bad stdout_visibility", lambda d: d.update({"stdout_visibility": "students"})),
        ("no tests", lambda d: d.update({"tests": []})),
    ]
    for what, change in broken:
        doc = copy.deepcopy(force)
        change(doc)
        if v.is_valid(doc):
            failures.append(f"the rubric schema accepts a rubric with {what}")
    return len(docs), len(broken)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

"""Checks configs/scene.schema.json against the shipped scenes and against broken ones.

Usage: check_schema.py CONFIGS_DIR. Exit 0 when every scene file validates and every
deliberately broken scene is rejected; 1 otherwise (each failure printed).
"""
import copy
import glob
import json
import os
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
    }
    for what, change in broken.items():
        scene = copy.deepcopy(base)
        change(scene)
        if validator.is_valid(scene):
            failures.append(f"the schema accepts a scene with an {what}")

    for f in failures:
        print("FAIL", f)
    print(f"{len(scenes)} scenes validated, {len(broken)} broken scenes checked, "
          f"{len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

"""Validates grader result files against Gradescope's results.json format
(gradescope_results.schema.json beside this file), and checks that the schema rejects
documents Gradescope would not take as meant (so that this check can fail).

Usage: check_results.py RESULTS.json...  Exit 0 when every file validates and every broken
document is rejected; 1 otherwise, each failure printed with its JSON path.
"""
import copy
import json
import os
import sys

import jsonschema

HERE = os.path.dirname(os.path.abspath(__file__))


def errors(validator, doc):
    return [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}"
            for e in validator.iter_errors(doc)]


def main(files):
    schema = json.load(open(os.path.join(HERE, "gradescope_results.schema.json")))
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    v = cls(schema)
    failures = []
    docs = []
    for path in files:
        try:
            doc = json.load(open(path))
        except (OSError, ValueError) as e:
            failures.append(f"{path}: not JSON: {e}")
            continue
        docs.append(doc)
        failures += [f"{path}: {e}" for e in errors(v, doc)]
        # What pinsim promises beyond the format: numbered tests, each with a status.
        numbers = [t.get("number") for t in doc.get("tests", [])]
        if len(set(numbers)) != len(numbers):
            failures.append(f"{path}: test numbers repeat: {numbers}")
        for i, t in enumerate(doc.get("tests", [])):
            for k in ("name", "number", "score", "max_score", "status", "output", "visibility"):
                if k not in t:
                    failures.append(f"{path}: tests/{i}: no {k}")
    if not docs:
        failures.append("no results file given")
    else:
        base = next((d for d in docs if d.get("tests")), docs[0])
        broken = [
            ("a score given as text", lambda d: d.update({"score": "10"})),
            ("an unknown visibility", lambda d: d.update({"visibility": "secret"})),
            ("an unknown stdout_visibility", lambda d: d.update({"stdout_visibility": "always"})),
            ("an unknown output_format", lambda d: d.update({"output_format": "pdf"})),
            ("a misspelt top-level key", lambda d: d.update({"scores": 1})),
            ("extra_data that is not an object", lambda d: d.update({"extra_data": []})),
            ("a leaderboard entry without a value",
             lambda d: d.update({"leaderboard": [{"name": "Time"}]})),
            ("a leaderboard order other than asc or desc",
             lambda d: d.update({"leaderboard": [{"name": "Time", "value": 1, "order": "up"}]})),
            ("no score anywhere", lambda d: (d.pop("score", None),
                                             [t.pop("score", None) for t in d.get("tests", [])])),
        ]
        if base.get("tests"):
            broken += [
                ("a test status other than passed or failed",
                 lambda d: d["tests"][0].update({"status": "ok"})),
                ("a test number that is not a string", lambda d: d["tests"][0].update({"number": 1})),
                ("a test output that is not a string",
                 lambda d: d["tests"][0].update({"output": ["a"]})),
                ("tags that are not strings", lambda d: d["tests"][0].update({"tags": [1]})),
                ("a test visibility of its own invention",
                 lambda d: d["tests"][0].update({"visibility": "students"})),
                ("a misspelt test key", lambda d: d["tests"][0].update({"max_points": 2})),
            ]
        for what, change in broken:
            doc = copy.deepcopy(base)
            change(doc)
            if v.is_valid(doc):
                failures.append(f"the results schema accepts {what}")
        print(f"{len(docs)} results files validated, {len(broken)} broken documents rejected")
    for f in failures:
        print("FAIL", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

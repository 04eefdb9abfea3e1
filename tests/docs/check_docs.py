"""Checks the project's front page and guides: every relative link in README.md, docs/*.md and
every folder's README.md (plugins, backends, sdk, tests, ...) points to a file or folder that exists (and, for `file.md#anchor`, to a heading of that file),
and README.md stays under a word limit.

Usage: check_docs.py SOURCE_DIR [--max-words N]   exit 0 when all holds, 1 otherwise (each
                                                  failure printed as FILE:LINE: what)
       check_docs.py --self-test                  checks that broken links, missing anchors
                                                  and a long README are each reported

Anchors are GitHub's: the heading lowercased, everything but letters, digits, spaces, `-`
and `_` removed, spaces turned into `-`; a repeated heading gets `-1`, `-2`, ...
"""
import os
import re
import sys
import tempfile

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML_SRC = re.compile(r"<(?:img|a)\b[^>]*?\b(?:src|href)=\"([^\"]+)\"", re.IGNORECASE)
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
FENCE = re.compile(r"^\s*(```|~~~)")
SKIP_DIRS = {"build", "node_modules", "out"}  # build trees, npm packages, run output


def prose_lines(text):
    """(line number, line) outside fenced code blocks, inline code spans blanked."""
    in_fence = False
    for number, line in enumerate(text.split("\n"), 1):
        if FENCE.match(line):
            in_fence = not in_fence
            continue
        if not in_fence:
            yield number, re.sub(r"`[^`]*`", lambda m: " " * len(m.group(0)), line)


def slug(heading):
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s, flags=re.UNICODE)
    return s.replace(" ", "-")


def anchors(path, cache={}):
    if path not in cache:
        found, seen = set(), {}
        with open(path, encoding="utf-8") as f:
            text = f.read()
        in_fence = False
        for line in text.split("\n"):
            if FENCE.match(line):
                in_fence = not in_fence
                continue
            m = None if in_fence else HEADING.match(line)
            if m:
                base = slug(m.group(2))
                n = seen.get(base, 0)
                seen[base] = n + 1
                found.add(base if n == 0 else f"{base}-{n}")
        cache[path] = found
    return cache[path]


def check_links(md_path, root, failures):
    with open(md_path, encoding="utf-8") as f:
        text = f.read()
    rel = os.path.relpath(md_path, root)
    for number, line in prose_lines(text):
        for target in LINK.findall(line) + HTML_SRC.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):  # http:, mailto:, ...
                continue
            file_part, _, anchor = target.partition("#")
            dest = md_path if not file_part else os.path.normpath(
                os.path.join(os.path.dirname(md_path), file_part))
            if not os.path.exists(dest):
                failures.append(f"{rel}:{number}: link to {target}: {file_part} does not exist")
                continue
            if anchor and dest.endswith(".md") and os.path.isfile(dest):
                if anchor not in anchors(dest):
                    failures.append(f"{rel}:{number}: link to {target}: no heading "
                                    f"#{anchor} in {os.path.relpath(dest, root)}")


def check(root, max_words):
    failures = []
    readme = os.path.join(root, "README.md")
    files = [readme]
    docs = os.path.join(root, "docs")
    if os.path.isdir(docs):
        files += sorted(os.path.join(docs, n) for n in os.listdir(docs) if n.endswith(".md"))
    for top, dirs, names in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in SKIP_DIRS)
        if top != root and "README.md" in names:
            files.append(os.path.join(top, "README.md"))
    for path in files:
        if os.path.isfile(path):
            check_links(path, root, failures)
        else:
            failures.append(f"{os.path.relpath(path, root)}: missing")
    if os.path.isfile(readme):
        with open(readme, encoding="utf-8") as f:
            words = len(f.read().split())
        if words >= max_words:
            failures.append(f"README.md: {words} words, the limit is under {max_words} "
                            "(move detail into a guide in docs/)")
    return failures


def self_test():
    """Each kind of failure is caught, and a correct tree passes."""
    with tempfile.TemporaryDirectory() as root:
        os.makedirs(os.path.join(root, "docs"))

        def write(name, text):
            with open(os.path.join(root, name), "w", encoding="utf-8") as f:
                f.write(text)

        os.makedirs(os.path.join(root, "plugins", "p"))
        write("plugins/p/README.md", "[up](../../README.md)\n")
        write("docs/guide.md", "# A guide\n## `pinsim share [SCENE] [--out game.html]`\n"
              "Back to [the front page](../README.md).\n```\n[in code](nowhere.md)\n```\n")
        write("README.md", "# x\nSee [the guide](docs/guide.md#pinsim-share-scene---out-gamehtml)"
              " and <img src=\"docs/guide.md\"> and [web](https://example.org) `[c](no.md)`.\n")
        ok = check(root, 1300)
        cases = {
            "a missing file": ("README.md", "[gone](docs/gone.md)\n", "docs/gone.md does not exist"),
            "a missing anchor": ("docs/guide.md", "[a](guide.md#no-such)\n", "no heading #no-such"),
            "a missing image": ("README.md", "<img src=\"docs/pictures/x.png\">\n", "does not exist"),
            "a folder's README": ("plugins/p/README.md", "[x](../q/README.md)\n", "does not exist"),
            "a long README": ("README.md", "word " * 1300 + "\n", "the limit is under 1300"),
        }
        errors = [] if not ok else [f"a correct tree fails: {ok}"]
        for what, (name, extra, expect) in cases.items():
            path = os.path.join(root, name)
            with open(path, encoding="utf-8") as f:
                before = f.read()
            write(name, before + extra)
            got = check(root, 1300)
            if not any(expect in g for g in got):
                errors.append(f"{what} is not reported (got {got})")
            write(name, before)
        for e in errors:
            print("self-test:", e)
        return 1 if errors else 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) not in (2, 4) or (len(argv) == 4 and argv[2] != "--max-words"):
        print(__doc__)
        return 2
    max_words = int(argv[3]) if len(argv) == 4 else 1300
    failures = check(argv[1], max_words)
    for f in failures:
        print(f)
    if not failures:
        print("README.md, docs/*.md and every folder's README.md: every relative link resolves;",
              "README.md under", max_words, "words")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

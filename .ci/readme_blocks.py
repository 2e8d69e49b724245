#!/usr/bin/env python3
"""Runs README.md's setup blocks exactly as a new user would type them.

A shell block is run when the line before its opening fence is
`<!-- ci: NAME [expect=PATH,...] -->`. Each block runs from the repository root in its own
`bash -e` (a failing line fails the block), with the user's environment; background jobs
and a PulseAudio daemon the block started are stopped afterwards. After the block, every
`expect` path must exist and be non-empty. Nothing is substituted (except that `apt-get`
goes through sudo when the runner is not root): a block that only works with edits does
not pass.

    .ci/readme_blocks.py [--list] [NAME...]     (no names: every marked block, in order)
"""
import argparse
import os
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MARK = re.compile(r"^\s*<!--\s*ci:\s*(\S+)((?:\s+\S+=\S+)*)\s*-->\s*$")
FENCE = re.compile(r"^(\s*)```(\w*)\s*$")

# Runs with the block in the same shell: stops what the block left running, and lets a
# block's `apt-get` go through sudo when this is not root (as a user would type it; a
# README cannot know whether its reader is root).
CLEANUP = """
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then
  apt-get() { sudo apt-get "$@"; }
fi
__tactus_ci_cleanup() {
  jobs -p | xargs -r kill 2>/dev/null || true
  if [ -n "${XDG_RUNTIME_DIR:-}" ]; then pulseaudio --kill 2>/dev/null || true; fi
}
trap __tactus_ci_cleanup EXIT
"""


def blocks(readme):
    """(name, expect paths, code, line number) of each marked block."""
    lines = open(readme, encoding="utf-8").read().splitlines()
    out = []
    i = 0
    while i < len(lines):
        m = MARK.match(lines[i])
        if not m:
            i += 1
            continue
        name, opts = m.group(1), m.group(2).split()
        expect = []
        for o in opts:
            key, _, value = o.partition("=")
            if key != "expect":
                sys.exit(f"README.md:{i + 1}: unknown option {key!r} in the ci marker")
            expect += [p for p in value.split(",") if p]
        f = FENCE.match(lines[i + 1]) if i + 1 < len(lines) else None
        if not f or f.group(2) not in ("sh", "bash"):
            sys.exit(f"README.md:{i + 1}: a ci marker must be followed by a ```sh fence")
        indent = f.group(1)
        body = []
        j = i + 2
        while j < len(lines) and not FENCE.match(lines[j]):
            line = lines[j]
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
            j += 1
        if j == len(lines):
            sys.exit(f"README.md:{i + 2}: unterminated code block")
        out.append((name, expect, "\n".join(body) + "\n", i + 2))
        i = j + 1
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*")
    ap.add_argument("--list", action="store_true", help="print the marked blocks and exit")
    args = ap.parse_args()
    found = blocks(os.path.join(ROOT, "README.md"))
    known = {b[0] for b in found}
    unknown = [n for n in args.names if n not in known]
    if unknown:
        sys.exit(f"no README block named {', '.join(unknown)} (have: {', '.join(sorted(known))})")
    chosen = [b for b in found if not args.names or b[0] in args.names]
    if args.list:
        for name, expect, code, line in chosen:
            print(f"== {name} (README.md:{line}; expects {expect or 'exit 0'})\n{code}")
        return
    failed = []
    for name, expect, code, line in chosen:
        print(f"\n---- README block {name!r} (README.md:{line}) ----\n{code}", flush=True)
        for p in expect:
            if os.path.exists(os.path.join(ROOT, p)):
                os.remove(os.path.join(ROOT, p))
        t = time.time()
        rc = subprocess.call(["bash", "-e", "-c", CLEANUP + code], cwd=ROOT)
        missing = [p for p in expect if not os.path.exists(os.path.join(ROOT, p))
                   or os.path.getsize(os.path.join(ROOT, p)) == 0]
        status = "ok" if rc == 0 and not missing else "FAILED"
        print(f"---- {name}: {status} (exit {rc}, {time.time() - t:.0f} s"
              + (f", missing or empty: {', '.join(missing)}" if missing else "") + ")", flush=True)
        if status != "ok":
            failed.append(name)
    if failed:
        sys.exit(f"README blocks failed: {', '.join(failed)}")
    print(f"\nall {len(chosen)} README blocks ran as written")


if __name__ == "__main__":
    main()

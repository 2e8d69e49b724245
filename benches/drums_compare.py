#!/usr/bin/env python3
"""Paired comparison of two `drums_eval.py` reports on the same songs, with song-level
bootstrap intervals (issue 10).

A held-out draw is 24 songs; a class's F moves by several thousandths when a handful of onsets
change, so a difference between two binaries needs its noise stated beside it. Both reports
must score the same songs with the same conditions and method names. For each condition and
class this prints F of A and of B (TP, FP, FN summed over songs, as `drums_eval.py` does),
the difference B − A and its percentile interval over `--resamples` bootstrap draws of the
songs (with replacement, the same draw for A and B: paired), and the same for the mean of all
condition × class F values.

  python3 benches/drums_compare.py A.json B.json [--method default] [--level 0.9]
      [--resamples 10000] [--seed 1] [--out REPORT.md]
  python3 benches/drums_compare.py --self-check   # the bootstrap against exact enumeration

Standard library only.
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import random
import sys

CLASSES = ("kick", "snare", "toms", "cymbals")


def f_of(tp, fp, fn):
    """F of summed counts (0 where nothing was found and nothing was there)."""
    d = 2 * tp + fp + fn
    return 2 * tp / d if d else 0.0


def table(report, method):
    """{(cond, song): {class: (tp, fp, fn)}} of one report's per-song counts."""
    out = {}
    for r in report["per_song"]:
        if r["method"] != method:
            continue
        out[(r["cond"], r["song"])] = {c: (r["counts"][c]["tp"], r["counts"][c]["fp"],
                                           r["counts"][c]["fn"]) for c in CLASSES}
    return out


def cells(a, b):
    """Per (cond, class): the songs' count triples of A and of B, songs in one order."""
    if set(a) != set(b):
        only = sorted(set(a) ^ set(b))[:3]
        sys.exit(f"the reports score different songs or conditions (e.g. {only})")
    conds = sorted({c for c, _ in a}, key=lambda c: (c != "isolated", c))
    songs = sorted({s for _, s in a})
    out = {}
    for cond in conds:
        for k in CLASSES:
            out[(cond, k)] = ([a[(cond, s)][k] for s in songs], [b[(cond, s)][k] for s in songs])
    return songs, out


def stats(cellmap, idx):
    """F of A, F of B per cell and the mean over cells, for the songs `idx` (with repeats)."""
    res = {}
    for key, (xa, xb) in cellmap.items():
        fa = f_of(*[sum(xa[i][j] for i in idx) for j in range(3)])
        fb = f_of(*[sum(xb[i][j] for i in idx) for j in range(3)])
        res[key] = (fa, fb)
    n = len(res)
    res["mean"] = (sum(v[0] for v in res.values()) / n, sum(v[1] for v in res.values()) / n)
    return res


def quantile(xs, q):
    """Linear-interpolation quantile of a sorted list (numpy's default)."""
    pos = q * (len(xs) - 1)
    lo = int(pos)
    hi = min(lo + 1, len(xs) - 1)
    return xs[lo] + (xs[hi] - xs[lo]) * (pos - lo)


def bootstrap(cellmap, n_songs, resamples, level, seed):
    """{key: (F A, F B, delta, low, high)}: the point values and the paired interval."""
    point = stats(cellmap, range(n_songs))
    rng = random.Random(seed)
    deltas = {k: [] for k in point}
    for _ in range(resamples):
        idx = [rng.randrange(n_songs) for _ in range(n_songs)]
        for k, (fa, fb) in stats(cellmap, idx).items():
            deltas[k].append(fb - fa)
    out = {}
    for k, (fa, fb) in point.items():
        d = sorted(deltas[k])
        out[k] = (fa, fb, fb - fa, quantile(d, (1 - level) / 2), quantile(d, (1 + level) / 2))
    return out


def exact(cellmap, n_songs, level):
    """The oracle: every one of the n^n equally likely resamples, enumerated."""
    point = stats(cellmap, range(n_songs))
    deltas = {k: [] for k in point}
    for idx in itertools.product(range(n_songs), repeat=n_songs):
        for k, (fa, fb) in stats(cellmap, idx).items():
            deltas[k].append(fb - fa)
    out = {}
    for k, v in deltas.items():
        v.sort()
        out[k] = (v[0], v[-1], quantile(v, (1 - level) / 2), quantile(v, (1 + level) / 2))
    return out


def self_check():
    """Checks the bootstrap against exact enumeration on four songs (256 resamples), and that
    a report compared with itself gives zero with a zero-width interval."""
    rng = random.Random(7)
    n = 4
    cellmap = {}
    for k in CLASSES:
        xa = [(rng.randrange(30), rng.randrange(10), rng.randrange(10)) for _ in range(n)]
        xb = [(tp + rng.randrange(-3, 4), fp + rng.randrange(0, 4), fn) for tp, fp, fn in xa]
        cellmap[("isolated", k)] = (xa, [(max(tp, 0), fp, fn) for tp, fp, fn in xb])
    want = exact(cellmap, n, 0.9)
    got = bootstrap(cellmap, n, 40000, 0.9, 3)
    worst = 0.0
    for k, (lo_all, hi_all, lo, hi) in want.items():
        g = got[k]
        # Every bootstrap interval lies inside the exact support, and its ends are within a
        # few thousandths of the exact quantiles (40,000 draws from 256 equally likely ones:
        # each resample's share is known to about 1/sqrt(40000 / 256) of itself, 8 %; the
        # quantiles of a discrete distribution move by at most one atom).
        assert lo_all - 1e-12 <= g[3] <= g[4] <= hi_all + 1e-12, (k, g, want[k])
        worst = max(worst, abs(g[3] - lo), abs(g[4] - hi))
    assert worst < 0.02, worst
    same = bootstrap({k: (v[0], v[0]) for k, v in cellmap.items()}, n, 500, 0.9, 1)
    assert all(v[2] == 0 and v[3] == 0 and v[4] == 0 for v in same.values()), same
    print(f"self-check passed: bootstrap quantiles within {worst:.4f} of exact enumeration")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a", nargs="?")
    ap.add_argument("b", nargs="?")
    ap.add_argument("--method", default="default")
    ap.add_argument("--level", type=float, default=0.9)
    ap.add_argument("--resamples", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out")
    ap.add_argument("--self-check", action="store_true")
    args = ap.parse_args()
    if args.self_check:
        self_check()
        return
    if not args.a or not args.b:
        ap.error("two reports (drums_eval.py --out X writes X.json), or --self-check")
    if not 0 < args.level < 1 or args.resamples < 1:
        ap.error("--level must be in (0, 1) and --resamples at least 1")
    reports = []
    for p in (args.a, args.b):
        try:
            with open(p) as f:
                reports.append(json.load(f))
        except (OSError, ValueError) as e:
            sys.exit(f"cannot read {p}: {e}")
    ta, tb = (table(r, args.method) for r in reports)
    if not ta or not tb:
        sys.exit(f"no per-song counts for method {args.method!r} in one of the reports")
    songs, cellmap = cells(ta, tb)
    res = bootstrap(cellmap, len(songs), args.resamples, args.level, args.seed)
    pct = round(100 * args.level)
    lines = [f"A: `{args.a}`; B: `{args.b}`; method `{args.method}`, {len(songs)} songs; "
             f"paired song bootstrap, {args.resamples} resamples, seed {args.seed}, {pct} % intervals.",
             "", f"| input | class | F A | F B | B − A | {pct} % interval |", "|---|---|---|---|---|---|"]
    for key, (fa, fb, d, lo, hi) in res.items():
        cond, k = key if key != "mean" else ("all", f"mean of {len(cellmap)}")
        lines.append(f"| {cond} | {k} | {fa:.4f} | {fb:.4f} | {d:+.4f} | {lo:+.4f} .. {hi:+.4f} |")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out:
        tmp = args.out + f".{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, args.out)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Scores the average of several trained drum models' activations (a seed ensemble), with
thresholds re-tuned on the validation songs the way train.py tunes them, on the same split
and data as train.py. For trials: the held-out family is whatever --held-out says.

  python3 models/drums/ensemble.py --data DIR --families timgm,csound,sonicpi,synth \
      --held-out sonicpi A.bin B.bin [--report-md OUT.md]

Needs numpy only; imports train.py for the front end, network and scoring.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import train as T  # noqa: E402


def add_common_args(ap):
    """The data, split and model arguments shared with decisions.py."""
    ap.add_argument("--data", required=True)
    ap.add_argument("--families", default=None)
    ap.add_argument("--held-out", default=",".join(T.HELD_OUT))
    ap.add_argument("models", nargs="+")


def averaged_activations(a):
    """train.py's validation and held-out songs for `a` (see add_common_args) and the
    models' activations on them, averaged: (D_va, D_ho, activations of D_va + D_ho)."""
    T.HELD_OUT[:] = a.held_out.split(",")
    items = T.songs(a.data)
    if a.families:
        items = [it for it in items if it[0] in a.families.split(",")]
    _, va, ho = T.split(items)
    D_va, D_ho = T.load(va, a.data, T.CONDS), T.load(ho, a.data, T.CONDS)
    acts = None
    for path in a.models:
        ps, _ = T.read_model(path)  # sets PAST, FUTURE, FLUX, WHITEN for this model
        one = [T.activations(ps, m) for (_, _, _, m, _) in D_va + D_ho]
        acts = one if acts is None else [x + y for x, y in zip(acts, one)]
    return D_va, D_ho, [x / len(a.models) for x in acts]


def main():
    ap = argparse.ArgumentParser()
    add_common_args(ap)
    ap.add_argument("--report-md", default=None)
    a = ap.parse_args()
    D_va, D_ho, acts = averaged_activations(a)
    D = D_va + D_ho
    thr = T.tune(acts[:len(D_va)], [t for (*_, t) in D_va])
    print("thresholds", thr, flush=True)
    lines = []
    sets = [("validation (training kits)", range(len(D_va)))] + [
        (f"held out: {f}", [len(D_va) + i for i, d in enumerate(D_ho) if d[0] == f]) for f in T.HELD_OUT]
    for name, idx in sets:
        for cond in T.CONDS:
            sel = [i for i in idx if D[i][2] == cond]
            if not sel:
                continue
            res = T.score([acts[i] for i in sel], [D[i][4] for i in sel], thr)
            cells = " | ".join(f"{r[2]:.2f} ({r[0]:.2f}/{r[1]:.2f})" for r in res)
            lines.append(f"| {name} | {cond} | {len(sel)} | {cells} |")
    md = ("| set | input | songs | kick F (P/R) | snare F (P/R) | toms F (P/R) | cymbals F (P/R) |\n"
          "|---|---|---|---|---|---|---|\n" + "\n".join(lines))
    print(md)
    if a.report_md:
        with open(a.report_md, "w") as f:
            f.write(md + "\n")


if __name__ == "__main__":
    main()

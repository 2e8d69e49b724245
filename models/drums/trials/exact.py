#!/usr/bin/env python3
"""Unrounded stand-in F (iso, sep) of trial models, for the guard in RULE_h10e.md.

  OPENBLAS_NUM_THREADS=1 corpus/.venv/bin/python models/drums/trials/exact.py \
      --data /work/data/i10drums2 A.bin B.bin ...

Stand-in = sonicpi, held out; the models' own thresholds; same scoring as train.py's report.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import train as T  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--data", required=True)
ap.add_argument("--stand-in", default="sonicpi")
ap.add_argument("models", nargs="+")
a = ap.parse_args()
T.HELD_OUT[:] = [a.stand_in]
items = [it for it in T.songs(a.data) if it[0] == a.stand_in]
_, _, ho = T.split(items)
D = T.load(ho, a.data, ["iso", "sep"])
for path in a.models:
    ps, thr = T.read_model(path)
    vals = []
    for cond in ("iso", "sep"):
        sel = [(m, t) for (_, _, c, m, t) in D if c == cond]
        res = T.score([T.activations(ps, m) for m, _ in sel], [t for _, t in sel], thr)
        vals.append([r[2] for r in res])
        print(path, cond, "kick/snare/toms/cymbals F", " ".join(f"{r[2]:.4f}" for r in res))
    print(path, "mean of 8", f"{sum(vals[0] + vals[1]) / 8:.4f}",
          "snare+toms", f"{(vals[0][1] + vals[0][2] + vals[1][1] + vals[1][2]) / 4:.4f}")

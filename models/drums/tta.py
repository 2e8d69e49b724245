#!/usr/bin/env python3
"""Test-time retuning of a drum perceptron (what it gains: models/drums/README.md).

The network runs on its normalised context window as it is and with the mel axis retuned by
each ratio (band b takes the value at frequency centre_b / ratio, linear between bands, then
the window normalisation again), and the activations are averaged. drums.rs does the same
for a `"TACTUSDT"` file (`Retuning`).

Screen ratio sets on the training families' validation songs (thresholds re-tuned per set):
    corpus/.venv/bin/python models/drums/tta.py --model crates/tactus-dsp/weights/drums.bin \
        --screen 1.1,1.2,1.3
Write a retuned file (ratios 1, 1/R, R; thresholds tuned on the validation songs, iso, sep
and mix pooled, as train.py tunes them):
    corpus/.venv/bin/python models/drums/tta.py --model NET.bin --spread 1.3 --out OUT.bin
"""
from __future__ import annotations

import argparse
import os
import struct
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import train as T  # noqa: E402

MAGIC = b"TACTUSDT"
TRAIN_FAMILIES = ("timgm", "csound", "sonicpi", "synth", "remix")


def ratios_for(spread):
    """Ratios 1, 1/R, R as the file stores them (f32)."""
    return [float(np.float32(r)) for r in (1.0, 1.0 / spread, spread)]


def validation(data, families=TRAIN_FAMILIES, held_out=tuple(T.HELD_OUT)):
    """The validation songs of the network's training families (train.py's split, which
    leaves the held-out families out)."""
    T.HELD_OUT[:] = list(held_out)
    items = [it for it in T.songs(data) if it[0] in families]
    _, va, _ = T.split(items)
    return T.load(va, data, list(T.CONDS))


def scores(ps, D, ratios, thr=None):
    acts = [T.activations(ps, m, ratios) for (_, _, _, m, _) in D]
    truths = [t for (*_, t) in D]
    if thr is None:
        thr = T.tune(acts, truths)
    f = []
    for cond in T.CONDS:
        sel = [i for i, d in enumerate(D) if d[2] == cond]
        f += [r[2] for r in T.score([acts[i] for i in sel], [truths[i] for i in sel], thr)]
    return thr, f


def write(path, net_path, ratios, thr):
    with open(net_path, "rb") as f:
        net = f.read()
    assert net.startswith(b"TACTUSDR"), "not a single network"
    with open(path + ".tmp", "wb") as f:
        f.write(MAGIC)
        f.write(struct.pack("<2I", 1, len(ratios)))
        f.write(np.asarray(ratios, dtype="<f4").tobytes())
        f.write(struct.pack("<I", len(net)))
        f.write(net)
        f.write(np.asarray(thr, dtype="<f4").tobytes())
    os.replace(path + ".tmp", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True, help="a single-network file (train.py --out)")
    ap.add_argument("--data", default="/work/data/drums")
    ap.add_argument("--screen", help="comma-separated spreads R to compare (ratios 1, 1/R, R)")
    ap.add_argument("--spread", type=float, help="write a retuned file with ratios 1, 1/R, R")
    ap.add_argument("--out", help="the retuned file to write")
    ap.add_argument("--families", default=",".join(TRAIN_FAMILIES),
                    help="the network's training families, whose validation songs tune the thresholds")
    ap.add_argument("--held-out", default=",".join(T.HELD_OUT), help="families never used (train.py --held-out)")
    a = ap.parse_args()
    ps, _ = T.read_model(a.model)
    assert T.RATIOS == [1.0], "already a retuned file"
    assert not (T.FLUX or T.BACK or T.WHITEN), "only a perceptron on mel frames (and its short view)"
    D = validation(a.data, a.families.split(","), a.held_out.split(","))
    print(f"validation: {len(D)} song conditions", flush=True)
    if a.screen:
        for spread in [None] + [float(s) for s in a.screen.split(",")]:
            ratios = [1.0] if spread is None else ratios_for(spread)
            thr, f = scores(ps, D, ratios)
            print(f"spread {spread or 1}: thresholds {[round(t, 3) for t in thr]}; F "
                  + "; ".join(f"{c} " + " / ".join(f"{v:.4f}" for v in f[4 * i:4 * i + 4])
                              for i, c in enumerate(T.CONDS))
                  + f"; mean of 12 {np.mean(f):.4f}", flush=True)
    if a.spread:
        ratios = ratios_for(a.spread)
        thr, f = scores(ps, D, ratios)
        print("thresholds", thr, f"mean of 12 {np.mean(f):.4f}", flush=True)
        write(a.out, a.model, ratios, thr)
        print("wrote", a.out)


if __name__ == "__main__":
    main()

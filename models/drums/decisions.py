#!/usr/bin/env python3
"""Trial of per-class decision rules on a trained model's activations (issue 10): an
adaptive threshold, threshold_c + k * (running mean of class c's activation over the
previous TAU hops), causal and free of latency, with k, TAU and the threshold tuned per
class on the validation songs (F over iso, sep and mix pooled, as train.py tunes), then
scored on the held-out family (the stand-in in trials).

  python3 models/drums/decisions.py --data DIR --families timgm,csound,sonicpi,synth \
      --held-out sonicpi MODEL.bin [MODEL2.bin ...]    # several: their activations averaged

Needs numpy only; imports train.py and ensemble.py.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import train as T  # noqa: E402
import ensemble as E  # noqa: E402


def running_mean(a, tau):
    """m[i] = mean-like EMA of a[..i-1] (previous hops only), time constant tau hops."""
    if tau <= 0:
        return np.zeros_like(a)
    al = np.exp(-1.0 / tau)
    m = np.zeros_like(a, dtype=np.float64)
    s = 0.0
    for i in range(len(a)):
        m[i] = s
        s = al * s + (1 - al) * a[i]
    return m


def pick_adaptive(a, thr, k, base):
    """train.pick with threshold thr + k * base[i]."""
    out = []
    armed, peak, last = True, 0.0, None
    for i, x in enumerate(a):
        t = thr + k * base[i]
        if not armed:
            peak = max(peak, x)
            if x < t or x < 0.5 * peak:
                armed = True
        if armed and x >= t and (last is None or i - last >= T.MIN_GAP):
            armed, peak, last = False, x, i
            out.append(i)
    return out


def score_class(acts, bases, truths, c, thr, k):
    tot = [0, 0, 0]
    for a, b, truth in zip(acts, bases, truths):
        est = [i * T.HOP_S for i in pick_adaptive(a[:, c], thr, k, b)]
        ref = [h["time_s"] for h in truth.get("onsets", {}).get(T.CLASSES[c], [])]
        for j, v in enumerate(T.match(est, ref)):
            tot[j] += v
    return T.prf(*tot)


def main():
    ap = argparse.ArgumentParser()
    E.add_common_args(ap)
    ap.add_argument("--ks", default="0,0.5,1,2")
    ap.add_argument("--taus", default="50,200")
    a = ap.parse_args()
    D_va, D_ho, acts = E.averaged_activations(a)
    D = D_va + D_ho
    nv = len(D_va)
    truths = [d[4] for d in D]
    ks = [float(v) for v in a.ks.split(",")]
    taus = [float(v) for v in a.taus.split(",")]
    for c in range(4):
        rows = []
        for tau in taus:
            bases = [running_mean(x[:, c], tau) for x in acts]
            for k in ks:
                if k == 0 and tau != taus[0]:
                    continue
                best = (-1, 0.5)
                for thr in np.arange(0.1, 0.95, 0.025):
                    f = score_class(acts[:nv], bases[:nv], truths[:nv], c, thr, k)[2]
                    if f > best[0]:
                        best = (f, float(thr))
                cells = []
                for cond in ("iso", "sep", "mix"):
                    sel = [nv + i for i, d in enumerate(D_ho) if d[2] == cond]
                    p, r, f = score_class([acts[i] for i in sel], [bases[i] for i in sel],
                                          [truths[i] for i in sel], c, best[1], k)
                    cells.append(f"{f:.3f} ({p:.2f}/{r:.2f})")
                vcells = []
                for cond in ("iso", "sep", "mix"):
                    sel = [i for i in range(nv) if D[i][2] == cond]
                    vcells.append(f"{score_class([acts[i] for i in sel], [bases[i] for i in sel], [truths[i] for i in sel], c, best[1], k)[2]:.3f}")
                rows.append(f"| {T.CLASSES[c]} | {tau:g} | {k:g} | {best[1]:.3f} | val pooled {best[0]:.3f} | val {' / '.join(vcells)} | held out {' / '.join(cells)} |")
                print(rows[-1], flush=True)


if __name__ == "__main__":
    main()

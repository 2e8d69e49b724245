#!/usr/bin/env python3
"""Where the levels ±1 of a melodic stem are lost, and what its pitch errors are (issue 16).

Reads the features files that `benches/bass_eval.py` wrote into OUT and the songs' truth,
and splits the misses of levels ±1 (every 100 ms bin, as `tactus eval` scores them) into:

* `false alarm`: the truth is silent, the render shows a level of 2 or more;
* `miss`: the truth is voiced and 2 or more, the render shows nothing;
* `wrong`: both voiced, more than one level apart (a wrong pitch or a wrong range).

It also replays the rendered pitch with the *true* range (the truth's lowest and highest
binned pitch, the range `tactus eval` gives the truth itself): the levels a perfect range
estimate would give this pitch track, so the gap to the engine's own levels is what the
range estimate costs. Then raw pitch accuracy (±50 cents, hops where the truth is voiced)
and the voiced errors by kind: an octave up or down (±50 cents of ±12 semitones), within
1.5 semitones (scoops, glides), or elsewhere; with `--registers`, the octave errors by the
true pitch's register (3-semitone bands).

    python3 benches/bass_eval.py --bin B --out OUT --held-out SONGS... --inputs mix --modes offline
    python3 benches/level_diag.py --out OUT --stem vocals [--input mix] [--mode offline] \\
        [--per-song] [--registers] SONGS...
"""
import argparse
import collections
import json
import math
import os

import numpy as np

from range_replay import binned_pitch, bins, st, truth_levels, within_1


def levels_in(s, lo, hi, n=8):
    """`tactus_dsp::discretize::Discretizer::level` in semitones (0 = unvoiced)."""
    out = np.zeros(len(s), int)
    for i, x in enumerate(s):
        if math.isnan(x):
            continue
        t = (x - lo) / (hi - lo) if hi > lo else 0.0
        out[i] = int(min(n, max(1, math.floor(n * t) + 1)))
    return out


def true_range(f0, hop_s):
    """The lowest and highest binned true pitch, in semitones (`truth_levels`' range)."""
    v = [st(x) for x in binned_pitch(f0, hop_s) if x > 0]
    return (min(v), max(v)) if v else None


def diagnose(truth, feat, stem):
    tl = truth_levels(truth["f0_hz"][stem], truth["hop_s"])
    el = np.array(feat["levels"][stem], int)
    n = max(len(tl), len(el))
    tl, el = np.pad(tl, (0, n - len(tl))), np.pad(el, (0, n - len(el)))
    kinds = collections.Counter()
    for a, b in zip(tl, el):
        kinds["ok" if abs(a - b) <= 1 else "false alarm" if a == 0 else "miss" if b == 0 else "wrong"] += 1
    f0 = feat["pitch_hz"][stem]
    s = np.array([st(x) if x and x > 0 else np.nan for x in f0])
    rng = true_range(truth["f0_hz"][stem], truth["hop_s"])
    ceiling = within_1(tl, bins(levels_in(s, *rng))) if rng else float("nan")
    errs, reg = collections.Counter(), collections.defaultdict(collections.Counter)
    for i, x in enumerate(truth["f0_hz"][stem]):
        if x <= 0:
            continue
        t = st(x)
        e = s[i] if i < len(s) else np.nan
        band = int(t // 3 * 3)
        reg[band]["voiced"] += 1
        if math.isnan(e):
            errs["unvoiced"] += 1
            continue
        d = e - t
        k = ("right" if abs(d) <= 0.5 else "octave up" if abs(d - 12) <= 0.5 else
             "octave down" if abs(d + 12) <= 0.5 else "within 1.5 st" if abs(d) <= 1.5 else "elsewhere")
        errs[k] += 1
        reg[band][k] += 1
    return kinds, within_1(tl, el), ceiling, errs, reg


def shares(c, keys):
    n = max(1, sum(c.values()))
    return " ".join(f"{k} {c[k] / n:.3f}" for k in keys)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="bass_eval.py's OUT")
    ap.add_argument("--stem", default="vocals", choices=["bass", "vocals", "other"])
    ap.add_argument("--input", default="mix", choices=["isolated", "mix"])
    ap.add_argument("--mode", default="offline", choices=["offline", "streaming"])
    ap.add_argument("--per-song", action="store_true")
    ap.add_argument("--registers", action="store_true")
    ap.add_argument("songs", nargs="+")
    a = ap.parse_args()
    lk = ["ok", "false alarm", "miss", "wrong"]
    ek = ["right", "unvoiced", "octave up", "octave down", "within 1.5 st", "elsewhere"]
    tot_k, tot_e, tot_r = collections.Counter(), collections.Counter(), collections.defaultdict(collections.Counter)
    engine, ceil = [], []
    for song in a.songs:
        song = song.rstrip("/")
        tag = f"{os.path.basename(os.path.dirname(song))}_{os.path.basename(song)}"
        path = os.path.join(a.out, f"{tag}.{a.input}.{a.mode}.features.json")
        truth = json.load(open(os.path.join(song, "truth.json")))
        kinds, lv, c, errs, reg = diagnose(truth, json.load(open(path)), a.stem)
        engine.append(lv)
        ceil.append(c)
        tot_k += kinds
        tot_e += errs
        for b, r in reg.items():
            tot_r[b] += r
        if a.per_song:
            print(f"{tag:40s} levels ±1 {lv:.3f} (true range {c:.3f}); {shares(errs, ek)}")
    print(f"{a.stem}, {a.input}, {a.mode}, {len(a.songs)} songs: levels ±1 {np.mean(engine):.3f}, "
          f"with the true range {np.nanmean(ceil):.3f}")
    print(f"  bins: {shares(tot_k, lk)}")
    print(f"  voiced hops: {shares(tot_e, ek)}")
    if a.registers:
        for b in sorted(tot_r):
            r = tot_r[b]
            print(f"  MIDI {b}-{b + 2}: {r['voiced']:6d} voiced hops, right {r['right'] / r['voiced']:.3f}, "
                  f"octave up {r['octave up'] / r['voiced']:.3f}, octave down {r['octave down'] / r['voiced']:.3f}")


if __name__ == "__main__":
    main()

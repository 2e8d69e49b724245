#!/usr/bin/env python3
"""Replays streaming pitch through causal level-range rules and scores levels ±1 (issue 16).

The streaming features file holds each hop's pitch after the gate and the fences, which the
range rule does not change. So a range rule can be tried offline, without a rebuild: exact
prefix quantiles, the held-note rule and the prior's padding, then 8 levels, then the
binner's lower median. The truth levels come from the whole song's range, as `tactus eval`
computes them. This is how README's "Streaming levels from a register prior" chose its
registers. The replay of the engine's own rule matches `tactus eval` to ±0.004 per song.

    python3 benches/bass_eval.py --bin B --out OUT --tuned SONGS... --inputs isolated --modes streaming
    python3 benches/range_replay.py --out OUT --stem bass SONGS... \\
        [--prior span:20 | register:28:62] [--fade 200] [--held-hops 5] [--truth-f0] \\
        [--quantile 0.01] [--octave-above W] [--min-hops 300]

`--truth-f0` replays the true f0 instead of the tracker's: a bound for any tracker under that
causal rule.
"""
import argparse
import bisect
import json
import math
import os

import numpy as np


def st(f):
    return 69.0 + 12.0 * math.log2(f / 440.0)


def binned_pitch(f0, hop_s, bin_s=0.1):
    """`tactus_eval::levels::bin_pitch`: per bin the lower median of its voiced hops when at
    least half of them are voiced, else 0."""
    bin_of = lambda i: int(math.floor(i * hop_s / bin_s + 1e-9))  # noqa: E731
    nb = bin_of(len(f0) - 1) + 1
    members, counts = [[] for _ in range(nb)], [0] * nb
    for i, f in enumerate(f0):
        counts[bin_of(i)] += 1
        if f > 0:
            members[bin_of(i)].append(f)
    return [sorted(v)[(len(v) - 1) // 2] if v and 2 * len(v) >= c else 0.0
            for v, c in zip(members, counts)]


def truth_levels(f0, hop_s, bin_s=0.1, levels=8):
    """`tactus_eval::levels::{bin_pitch, discretize}`."""
    binned = binned_pitch(f0, hop_s, bin_s)
    v = [st(x) for x in binned if x > 0]
    lo, hi = min(v), max(v)
    return np.array([0 if x <= 0 else 1 if hi <= lo else
                     int(min(1 + math.floor((st(x) - lo) / (hi - lo) * levels), levels))
                     for x in binned])


def held(s, k, tol, above=0):
    """`tactus_dsp::discretize::held_mask` on semitones (NaN = unvoiced); with `above` > 0,
    also not a hop with a hop an octave below it (±1 semitone) within `above` hops on either
    side (an octave-up error next to its true note; a replay-only rule, not the engine's)."""
    n, out = len(s), np.zeros(len(s), bool)
    for i in range(n):
        if math.isnan(s[i]) or (k and (i < k or i + k >= n)):
            continue
        if k:
            w = s[i - k:i + k + 1]
            if np.isnan(w).any() or not bool(np.all(np.abs(w - s[i]) <= tol)):
                continue
        if above:
            a, b = max(0, i - above), min(n, i + above + 1)
            if bool(np.any(np.abs(s[a:b] - (s[i] - 12.0)) <= 1.0)):
                continue
        out[i] = True
    return out


def replay(s, prior, fade, k, p=0.01, tol=1.0, min_share=0.25, min_hops=300, levels=8, above=0):
    """Per-hop levels of the streaming rule (`HeldRange::with_prior`), exact quantiles."""
    m = max(k, above)
    h = held(s, k, tol, above) if m else None
    every, kept = [], []
    nv = nh = 0
    out = np.zeros(len(s), int)
    for i, x in enumerate(s):
        if not math.isnan(x):
            bisect.insort(every, x)
            nv += 1
        if m and i >= m and h[i - m]:
            bisect.insort(kept, s[i - m])
            nh += 1
        v = kept if m and nh >= max(1, min_hops) and nh >= min_share * nv else every
        if math.isnan(x) or not v:
            continue
        j = int(round((len(v) - 1) * p))
        lo, hi = v[j], v[len(v) - 1 - j]
        w = fade / (fade + nv)
        if prior[0] == "span":
            pad = max(0.0, prior[1] - (hi - lo)) * w / 2
            lo, hi = lo - pad, hi + pad
        else:
            lo, hi = lo - w * max(0.0, lo - prior[1]), hi + w * max(0.0, prior[2] - hi)
        out[i] = 1 if hi <= lo else int(min(levels, max(1, math.floor(levels * (x - lo) / (hi - lo)) + 1)))
    return out


def bins(lv, per=10):
    """`tactus_dsp::binner::LevelBinner` for 10 ms hops in 100 ms bins."""
    out = []
    for b in range(0, len(lv), per):
        seg = lv[b:b + per]
        v = np.sort(seg[seg > 0])
        out.append(v[(len(v) - 1) // 2] if 2 * len(v) > len(seg) else 0)
    return np.array(out, int)


def within_1(t, e):
    n = max(len(t), len(e))
    t, e = np.pad(t, (0, n - len(t))), np.pad(e, (0, n - len(e)))
    return float(np.mean(np.abs(t - e) <= 1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="bass_eval.py's OUT (streaming features)")
    ap.add_argument("--stem", default="bass", choices=["bass", "vocals"])
    ap.add_argument("--input", default="isolated", choices=["isolated", "mix"])
    ap.add_argument("--prior", default=None, help="span:ST or register:LO_ST:HI_ST (MIDI)")
    ap.add_argument("--fade", type=float, default=None, help="voiced hops (default: the engine's)")
    ap.add_argument("--held-hops", type=int, default=None)
    ap.add_argument("--truth-f0", action="store_true")
    ap.add_argument("--quantile", type=float, default=0.01, help="cut from each end (the engine: 0.01)")
    ap.add_argument("--octave-above", type=int, default=0, metavar="W",
                    help="leave out of the range hops with a hop an octave below within W hops (replay only)")
    ap.add_argument("--min-hops", type=int, default=300, help="kept hops before the kept range is used")
    ap.add_argument("--pitch-of", default="streaming", choices=["streaming", "offline"],
                    help="replay the pitch of the streaming or of the offline features file")
    ap.add_argument("songs", nargs="+")
    a = ap.parse_args()
    bass = a.stem == "bass"
    prior = ([("register", 28.0, 62.0)] if bass else [("register", 57.0, 79.0)])[0]
    if a.prior:
        kind, *v = a.prior.split(":")
        prior = (kind, *map(float, v))
    fade = a.fade or (200.0 if prior[0] == "register" else 3000.0)
    k = a.held_hops if a.held_hops is not None else (5 if bass and a.input == "isolated" else 0)
    scores = []
    for song in a.songs:
        song = song.rstrip("/")
        tag = f"{os.path.basename(os.path.dirname(song))}_{os.path.basename(song)}"
        truth = json.load(open(os.path.join(song, "truth.json")))
        tl = truth_levels(truth["f0_hz"][a.stem], truth["hop_s"])
        if a.truth_f0:
            f0 = truth["f0_hz"][a.stem]
        else:
            feat = os.path.join(a.out, f"{tag}.{a.input}.{a.pitch_of}.features.json")
            f0 = json.load(open(feat))["pitch_hz"][a.stem]
        s = np.array([st(f) if f > 0 else np.nan for f in f0])
        r = within_1(tl, bins(replay(s, prior, fade, k, p=a.quantile, min_hops=a.min_hops,
                                      above=a.octave_above)))
        scores.append(r)
        print(f"{tag:40s} {r:.3f}")
    print(f"mean over {len(scores)} songs: {np.mean(scores):.4f} "
          f"({a.stem}, {a.input}, prior {prior}, fade {fade:g}, held hops {k})")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Where the drum transcriber's snare is lost (issue 10): recall by velocity and by what
sounds with the hit, and what its false positives sit on.

Runs a drum model file (default: the embedded `crates/tactus-dsp/weights/drums.bin`) over the
features `models/drums/train.py` dumps, with that script's own activations, peak picking and
split, and sorts the snare hits and picks:

* every true snare hit by velocity (ghost ≤ 45, medium ≤ 80, loud) and by the other classes
  struck within 30 ms of it, with how many of them no pick matched (±50 ms, one to one);
* every unmatched snare pick by the truth within ±50 ms of it (a class name with "<=60" for
  a hit of velocity 60 or less), or "none"; for those, the distance to the nearest hit.

    corpus/.venv/bin/python benches/drum_snare_errors.py --data /work/data/drums \\
        [--split val|held] [--cond iso|sep|mix] [--model FILE]
"""
import argparse
import collections
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "models", "drums"))
import train as T  # noqa: E402


def velocity_band(v):
    return "ghost" if v <= T.GHOST_VEL else ("medium" if v <= 80 else "loud")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default="val", choices=["val", "held"])
    ap.add_argument("--cond", default="iso", choices=["iso", "sep", "mix"])
    ap.add_argument("--model", default=T.DEFAULT_OUT)
    a = ap.parse_args()
    ps, thr = T.read_model(a.model)
    _, va, ho = T.split(T.songs(a.data))
    data = T.load(va if a.split == "val" else ho, a.data, [a.cond])
    hits, missed, false_near, none_dist = (collections.Counter(), collections.Counter(),
                                           collections.Counter(), [])
    for _fam, _song, _c, mel, truth in data:
        act = T.activations(ps, mel)
        on = truth["onsets"]
        every = [(h["time_s"], n, h.get("velocity", 127)) for n in T.CLASSES for h in on.get(n, [])]
        picks = [i * T.HOP_S for i in T.pick(act[:, 1], thr[1])]
        used = [False] * len(picks)
        for h in sorted(on.get("snare", []), key=lambda h: h["time_s"]):
            t = h["time_s"]
            with_ = tuple(sorted({n for tt, n, _ in every if n != "snare" and abs(tt - t) < 0.03}))
            key = (velocity_band(h.get("velocity", 127)), with_)
            hits[key] += 1
            for j, e in enumerate(picks):
                if not used[j] and abs(e - t) <= T.WINDOW_S:
                    used[j] = True
                    break
            else:
                missed[key] += 1
        for j, e in enumerate(picks):
            if used[j]:
                continue
            near = [(n, v) for tt, n, v in every if abs(tt - e) <= T.WINDOW_S]
            key = tuple(sorted({n + ("<=60" if v <= 60 else "") for n, v in near})) or ("none",)
            false_near[key] += 1
            if not near and every:
                none_dist.append(min((tt - e for tt, _, _ in every), key=abs))
    print(f"snare hits ({a.split}, {a.cond}) by velocity and what sounds within 30 ms: total / missed / recall")
    for k in sorted(hits, key=lambda k: -hits[k]):
        print(f"  {k[0]:7s} {'+'.join(k[1]) or 'alone':24s} {hits[k]:5d} {missed[k]:5d} {1 - missed[k] / hits[k]:.2f}")
    print(f"snare false positives: {sum(false_near.values())}")
    for k in sorted(false_near, key=lambda k: -false_near[k]):
        print(f"  near {'+'.join(k):28s} {false_near[k]}")
    if none_dist:
        early = sum(1 for d in none_dist if 0.05 < d <= 0.1)
        print(f"  of the {len(none_dist)} near no hit, {early} come 50-100 ms before the nearest one")


if __name__ == "__main__":
    main()

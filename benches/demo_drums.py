#!/usr/bin/env python3
"""Scores the bundled demo's drum onsets and index finger against its truth (issue 10's demo
target: "the index finger is up only where a kick or snare is").

`examples/demo.ogg` is the two committed corpus fixtures one after the other (`bwv347_120bpm`,
then `bwv66-6_96bpm`, 8 s each; their mixes correlate 0.998 with the demo's), so its truth is
theirs with the second shifted by 8 s. Reads a render's pattern and features files:

    tactus render examples/demo.ogg -o demo.json --features demo-features.json [--drums bands]
    python3 benches/demo_drums.py demo.json demo-features.json

Prints per class the onsets' precision / recall / F at ±50 ms (one to one, in time order, as
`tactus eval` matches them), and how many 100 ms bins raise the index finger (kick or snare
cell), how many of those hold a true kick or snare within the bin ±50 ms, and what sounds
at each false kick or snare onset. Standard library only.
"""
import json
import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
PARTS = [(0.0, "bwv347_120bpm"), (8.0, "bwv66-6_96bpm")]
CLASSES = ("kick", "snare", "toms", "cymbals")
TOL = 0.05


def truth():
    ref = {c: [] for c in CLASSES}
    for off, song in PARTS:
        with open(os.path.join(ROOT, "corpus", "fixtures", song, "truth.json")) as f:
            t = json.load(f)
        for c in CLASSES:
            ref[c] += [(off + h["time_s"], h.get("velocity", 0)) for h in t["onsets"][c]]
    return {c: sorted(v) for c, v in ref.items()}


def match(est, ref):
    """Greedy one-to-one matching in time order; the matched reference indices."""
    used, hits = set(), []
    for e in sorted(est):
        for j, r in enumerate(ref):
            if j not in used and abs(r - e) <= TOL:
                used.add(j)
                hits.append(e)
                break
    return hits, used


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        pattern = json.load(f)
    with open(sys.argv[2]) as f:
        features = json.load(f)
    ref = truth()
    for c in CLASSES:
        est = features["onsets_s"].get(c, [])
        times = [t for t, _ in ref[c]]
        hits, used = match(est, times)
        tp, fp, fn = len(hits), len(est) - len(hits), len(times) - len(used)
        p = tp / (tp + fp) if tp + fp else 0.0
        r = tp / (tp + fn) if tp + fn else 0.0
        f = 2 * p * r / (p + r) if p + r else 0.0
        print(f"{c}: {len(est)} onsets, {len(times)} true: P {p:.2f} R {r:.2f} F {f:.2f}")
        if c in ("kick", "snare"):
            for e in sorted(set(est) - set(hits)):
                there = [f"{k} v{v}" for k in CLASSES for t, v in ref[k] if abs(t - e) <= TOL]
                print(f"  false at {e:.2f} s: {', '.join(there) or 'no drum'}")
            missed = [(t, v) for j, (t, v) in enumerate(ref[c]) if j not in used]
            for t, v in missed:
                print(f"  missed at {t:.2f} s (velocity {v})")
    # The index finger: cells 2 and 3 of each frame (thumb, index, middle, ring, pinky).
    bin_s = pattern["bin_ms"] / 1000.0
    kicks_snares = [t for c in ("kick", "snare") for t, _ in ref[c]]
    up = with_hit = 0
    for b, frame in enumerate(pattern["frames"]):
        cells = bytes.fromhex(frame)
        if cells[2] or cells[3]:
            up += 1
            lo, hi = b * bin_s - TOL, (b + 1) * bin_s + TOL
            with_hit += any(lo <= t < hi for t in kicks_snares)
    print(f"index finger up in {up} of {len(pattern['frames'])} bins; {with_hit} of them hold a "
          f"true kick or snare (bin ±{TOL * 1000:.0f} ms)")


if __name__ == "__main__":
    main()

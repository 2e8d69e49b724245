#!/usr/bin/env python3
"""Why note onsets are missed or false: a diagnosis of the melodic stems' note-onset cell.

Reads the features files that `benches/bass_eval.py --out OUT` leaves behind
(`OUT/<family>_<song>.<input>.<mode>.features.json`) and each song's `truth.json`, matches the
reported note onsets of bass and vocals to the truth's note starts (±50 ms, one to one, nearest
first, as `tactus eval` scores them) and sorts what is left over:

missed true onsets
  repeat    the note has the previous note's pitch (±0.5 semitone) and starts less than 150 ms
            after it ended (a re-attack inside a held pitch: the pitch track cannot see it)
  late      an unmatched reported onset lies 50–200 ms after it
  early     an unmatched reported onset lies 50–200 ms before it
  unvoiced  the reported pitch is unvoiced on most of the note's first 100 ms
  short     the note lasts less than 80 ms
  other     none of these (e.g. the reported pitch never settles on the note)
false reported onsets
  timing    a true onset lies within 200 ms (it is late, early or a double)
  voicing   the truth is silent there (a voicing false alarm)
  in-note   inside a sounding true note (pitch wobble, octave jump, a re-attack the truth lacks)

    python3 benches/note_onset_diag.py --out OUT --songs SONG... [--input mix] [--mode offline]
"""
import argparse
import json
import math
import os
import sys
from collections import Counter

WIN = 0.05


def truth_onsets(t, stem):
    n = t.get("note_onsets_s", {}) or {}
    if stem in n:
        return sorted(n[stem])
    f0, hop = t["f0_hz"][stem], t["hop_s"]
    out, prev = [], 0.0
    for i, f in enumerate(f0):
        v = f > 0
        if v and (prev <= 0 or abs(12 * math.log2(f / prev)) >= 0.5):
            out.append(i * hop)
        prev = f if v else 0.0
    return out


def match(ref, est, win=WIN):
    """Greedy one-to-one matching, nearest pairs first. Returns (pairs, unmatched ref, unmatched est)."""
    cand = sorted((abs(r - e), i, j) for i, r in enumerate(ref) for j, e in enumerate(est)
                  if abs(r - e) <= win)
    ur, ue, pairs = set(range(len(ref))), set(range(len(est))), []
    for _d, i, j in cand:
        if i in ur and j in ue:
            ur.discard(i)
            ue.discard(j)
            pairs.append((i, j))
    return pairs, sorted(ur), sorted(ue)


def st(f):
    return 12 * math.log2(f / 440.0) + 69


def note_span(f0, hop, t0):
    """(pitch in semitones, end time) of the true note that starts at t0."""
    i = int(math.ceil(t0 / hop - 1e-6))  # the first hop at or after the start
    vals = []
    j = i
    while j < len(f0) and f0[j] > 0:
        if vals and abs(st(f0[j]) - vals[0]) >= 0.5 and j - i > 3:
            break
        vals.append(st(f0[j]))
        j += 1
    p = sorted(vals[:8])[len(vals[:8]) // 2] if vals else None
    return p, j * hop


def prev_note(f0, hop, t0):
    """(pitch, end time) of the sounding stretch that ends before t0 (None if none within 0.5 s)."""
    i = int(round(t0 / hop)) - 1
    while i >= 0 and f0[i] <= 0 and (t0 - i * hop) < 0.5:
        i -= 1
    if i < 0 or f0[i] <= 0:
        return None, None
    return st(f0[i]), (i + 1) * hop


def diagnose(song, feat, stem):
    t = json.load(open(os.path.join(song, "truth.json")))
    f = json.load(open(feat))
    ref = truth_onsets(t, stem)
    est = sorted(f.get("onsets_s", {}).get(stem, []))
    f0 = t["f0_hz"][stem]
    hop = t["hop_s"]
    pe = f.get("pitch_hz", {}).get(stem, [])
    ehop = f.get("hop_s", 0.01)
    pairs, ur, ue = match(ref, est)
    miss, fals = Counter(), Counter()
    lat = [est[j] - ref[i] for i, j in pairs]
    for i in ur:
        r = ref[i]
        p, end = note_span(f0, hop, r)
        pp, pend = prev_note(f0, hop, r - 1e-9)
        # a true onset inside continuous voicing with the same pitch (no gap in f0) also counts
        i0 = int(math.ceil(r / hop - 1e-6))
        cont = i0 > 0 and f0[i0 - 1] > 0 and f0[i0] > 0 and abs(st(f0[i0 - 1]) - st(f0[i0])) < 0.5
        after = [est[j] - r for j in ue if 0.05 < est[j] - r <= 0.2]
        before = [r - est[j] for j in ue if 0.05 < r - est[j] <= 0.2]
        k0, k1 = int(round(r / ehop)), int(round((r + 0.1) / ehop))
        seg = pe[k0:k1]
        unv = sum(1 for v in seg if v <= 0) > len(seg) / 2 if seg else True
        if cont or (p is not None and pp is not None and abs(p - pp) < 0.5 and r - pend < 0.15):
            miss["repeat"] += 1
        elif after:
            miss["late"] += 1
        elif before:
            miss["early"] += 1
        elif unv:
            miss["unvoiced"] += 1
        elif end - r < 0.08:
            miss["short"] += 1
        else:
            miss["other"] += 1
    for j in ue:
        e = est[j]
        if any(abs(e - r) <= 0.2 for r in ref):
            fals["timing"] += 1
            continue
        k = int(round(e / hop))
        if k >= len(f0) or f0[k] <= 0:
            fals["voicing"] += 1
        else:
            fals["in-note"] += 1
    return len(ref), len(est), len(pairs), miss, fals, lat


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True, help="bass_eval.py's --out folder")
    ap.add_argument("--songs", nargs="+", required=True)
    ap.add_argument("--input", default="mix")
    ap.add_argument("--mode", default="offline")
    ap.add_argument("--stems", default="bass,vocals")
    ap.add_argument("--per-song", action="store_true")
    a = ap.parse_args()
    for stem in a.stems.split(","):
        tot = Counter()
        miss, fals = Counter(), Counter()
        lat = []
        for song in a.songs:
            s = song.rstrip("/")
            tag = f"{os.path.basename(os.path.dirname(s))}_{os.path.basename(s)}.{a.input}.{a.mode}"
            feat = os.path.join(a.out, tag + ".features.json")
            if not os.path.exists(feat):
                print("missing", feat, file=sys.stderr)
                continue
            nr, ne, nm, m, fl, la = diagnose(s, feat, stem)
            tot.update(ref=nr, est=ne, hit=nm)
            miss.update(m)
            fals.update(fl)
            lat += la
            if a.per_song:
                print(f"  {stem} {os.path.basename(s)}: ref {nr} est {ne} hit {nm} "
                      f"missed {dict(m)} false {dict(fl)}")
        p = tot["hit"] / max(1, tot["est"])
        r = tot["hit"] / max(1, tot["ref"])
        f = 2 * p * r / max(1e-9, p + r)
        lat.sort()
        med = lat[len(lat) // 2] * 1000 if lat else float("nan")
        print(f"{stem} {a.input} {a.mode}: true {tot['ref']} reported {tot['est']} matched {tot['hit']} "
              f"P {p:.3f} R {r:.3f} F {f:.3f} (pooled); matched median offset {med:+.0f} ms")
        print(f"  missed {tot['ref'] - tot['hit']}: " + ", ".join(f"{k} {v}" for k, v in miss.most_common()))
        print(f"  false {tot['est'] - tot['hit']}: " + ", ".join(f"{k} {v}" for k, v in fals.most_common()))


if __name__ == "__main__":
    sys.exit(main())

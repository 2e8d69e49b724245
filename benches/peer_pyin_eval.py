#!/usr/bin/env python3
"""librosa.pyin on the isolated vocals and bass stems of corpus songs, scored like `tactus eval`.

The peer row of README's issue-16 tables: for each song folder (stems + truth.json, as written
by corpus/generate.py, corpus/drums.py or corpus/sung.py), runs librosa.pyin on `vocals.wav`
and `bass.wav` with Tactus's stem ranges (vocals 70–1400 Hz, bass 35–400 Hz, docs/DESIGN.md)
on 10 ms hops at 22,050 Hz, and scores raw pitch accuracy (±50 cents over the truth's voiced
hops; an unvoiced estimate counts as wrong, as in `tactus eval`), voicing recall and false alarm
against the truth's `f0_hz`. Prints the mean per group and writes per-song rows as JSON.

Needs librosa (benches/peers/requirements.txt):
    python3 -m venv V && V/bin/pip install -r benches/peers/requirements.txt
    V/bin/python benches/peer_pyin_eval.py --out rows.json --group sung-held-out SONG... [--group NAME SONG...]
"""
import argparse
import json
import math
import sys

import librosa
import numpy as np

RANGES = {"vocals": (70.0, 1400.0), "bass": (35.0, 400.0)}
SR = 22050
HOP_S = 0.01


def scores(ref, est):
    ref = np.asarray(ref, dtype=float)
    est = np.asarray(est, dtype=float)
    n = len(ref)
    if len(est) < n:
        est = np.concatenate([est, np.zeros(n - len(est))])
    est = est[:n]
    rv = ref > 0
    ev = est > 0
    both = rv & ev
    cents = np.zeros(n)
    cents[both] = 1200.0 * np.abs(np.log2(est[both] / ref[both]))
    ok = both & (cents < 50.0)
    return {
        "rpa": ok.sum() / max(rv.sum(), 1),
        "voicing_recall": both.sum() / max(rv.sum(), 1),
        "voicing_false_alarm": (ev & ~rv).sum() / max((~rv).sum(), 1),
    }


def run(song, stem):
    y, _ = librosa.load(f"{song}/{stem}.wav", sr=SR, mono=True)
    fmin, fmax = RANGES[stem]
    hop = int(round(SR * HOP_S))
    # frame_length: 2048 (93 ms) for the voice, 4096 for the bass (two periods of 35 Hz are 57 ms,
    # and pyin's YIN half-frame must hold them).
    frame = 2048 if stem == "vocals" else 4096
    f0, voiced, _ = librosa.pyin(y, fmin=fmin, fmax=fmax, sr=SR, frame_length=frame,
                                 hop_length=hop, center=True)
    f0 = np.where(voiced & np.isfinite(f0), f0, 0.0)
    # Hop i of librosa (center=True) is at i * hop / SR seconds; resample to the truth's hop.
    return f0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--group", nargs="+", action="append", required=True,
                    metavar=("NAME", "SONG"), help="a group name and its song folders")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    rows = []
    for name, *songs in a.group:
        for song in songs:
            with open(f"{song}/truth.json") as fh:
                t = json.load(fh)
            h = float(t.get("hop_s", HOP_S))
            for stem in ("vocals", "bass"):
                ref = t["f0_hz"].get(stem)
                if ref is None:
                    continue
                est = run(song, stem)
                if abs(h - HOP_S) > 1e-9:
                    idx = np.round(np.arange(len(ref)) * h / HOP_S).astype(int)
                    est = np.where(idx < len(est), est[np.minimum(idx, len(est) - 1)], 0.0)
                row = {"group": name, "song": song.rstrip("/").split("/")[-1], "stem": stem}
                row.update(scores(ref, est))
                rows.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    with open(a.out, "w") as fh:
        json.dump(rows, fh, indent=1)
    print("| group | songs | vocals RPA | vocals voicing R / FA | bass RPA | bass voicing R / FA |")
    print("|---|---|---|---|---|---|")
    for name, *songs in a.group:
        def m(stem, k):
            v = [r[k] for r in rows if r["group"] == name and r["stem"] == stem]
            return f"{np.mean(v):.3f}" if v else "–"
        print(f"| {name} | {len(songs)} | {m('vocals', 'rpa')} | {m('vocals', 'voicing_recall')} / "
              f"{m('vocals', 'voicing_false_alarm')} | {m('bass', 'rpa')} | "
              f"{m('bass', 'voicing_recall')} / {m('bass', 'voicing_false_alarm')} |")


if __name__ == "__main__":
    main()

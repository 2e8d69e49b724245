#!/usr/bin/env python3
"""When does the tracker change note, and when does the audio? (issue 16, chorale vocals).

For each note change of a stem's truth (two voiced runs at least 0.2 s long, at most 5 hops
apart, medians at least 0.8 semitone apart), prints the median number of hops after the
truth's new note at which (a) the rendered pitch is nearer the new note than the old one and
(b) the stem's audio holds more of the new note than of the old: the sum of the magnitudes of
harmonics 2–4 in a 60 ms Hann window centred on the hop.

    python3 benches/bass_eval.py --bin B --out OUT --tuned SONGS... --inputs isolated --modes offline
    python3 benches/note_change_lag.py --out OUT [--stem vocals] SONGS...
"""
import argparse
import json
import os
import wave

import numpy as np


def st(f):
    return 69 + 12 * np.log2(f / 440)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="bass_eval.py's OUT (isolated offline features)")
    ap.add_argument("--stem", default="vocals")
    ap.add_argument("songs", nargs="+")
    a = ap.parse_args()
    for song in a.songs:
        song = song.rstrip("/")
        tag = f"{os.path.basename(os.path.dirname(song))}_{os.path.basename(song)}"
        t = np.array(json.load(open(os.path.join(song, "truth.json")))["f0_hz"][a.stem])
        feat = os.path.join(a.out, f"{tag}.isolated.offline.features.json")
        e = np.array(json.load(open(feat))["pitch_hz"][a.stem])
        with wave.open(os.path.join(song, f"{a.stem}.wav")) as w:
            sr, ch = w.getframerate(), w.getnchannels()
            x = np.frombuffer(w.readframes(w.getnframes()), "<i2").astype(float)
        x = x.reshape(-1, ch).mean(1)
        half = int(0.03 * sr)

        def mag(i, f):
            s = int(i * 0.01 * sr)
            seg = x[max(0, s - half):s + half]
            tt = np.arange(len(seg)) / sr
            win = np.hanning(len(seg))
            return sum(abs(np.sum(seg * win * np.exp(-2j * np.pi * h * f * tt))) for h in (2, 3, 4))

        runs, i = [], 0
        while i < len(t):
            if t[i] > 0:
                j = i
                while j < len(t) and t[j] > 0:
                    j += 1
                runs.append((i, j))
                i = j
            else:
                i += 1
        trk, aud = [], []
        for (a0, a1), (b0, b1) in zip(runs, runs[1:]):
            if b0 - a1 > 5 or a1 - a0 < 20 or b1 - b0 < 20:
                continue
            fo, fn = np.median(t[a1 - 10:a1]), np.median(t[b0 + 10:b0 + 20])
            if abs(st(fn) - st(fo)) < 0.8:
                continue
            k = next((i for i in range(b0 - 5, min(b0 + 30, len(e)))
                      if e[i] > 0 and abs(st(e[i]) - st(fn)) < abs(st(e[i]) - st(fo))), None)
            q = next((i for i in range(b0 - 5, b0 + 30) if mag(i, fn) > mag(i, fo)), None)
            if k is not None and q is not None:
                trk.append(k - b0)
                aud.append(q - b0)
        if not trk:
            print(f"{tag}: no note changes")
            continue
        print(f"{tag}: {len(trk)} note changes; tracker {np.median(trk):+.0f} hops, "
              f"audio {np.median(aud):+.0f} hops after the truth's new note (medians)")


if __name__ == "__main__":
    main()

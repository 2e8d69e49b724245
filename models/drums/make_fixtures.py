#!/usr/bin/env python3
"""Cuts the held-out drum fixtures that CI scores the transcriber on
(crates/tactus-engine/tests/fixtures/drums/): the first SECONDS of two songs from the
families that no model was trained or tuned on (musescore and fluid, see
models/drums/README.md), as FLAC (drums mono, mix stereo) with their truth trimmed.

  corpus/.venv/bin/python models/drums/make_fixtures.py --data /work/data/drums
"""
import argparse
import json
import os

import numpy as np
import soundfile as sf

SONGS = ["musescore/std00_s00", "fluid/room08_s07"]
SECONDS = 8.0
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = os.path.join(ROOT, "crates", "tactus-engine", "tests", "fixtures", "drums")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    a = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    for song in SONGS:
        src = os.path.join(a.data, song)
        name = song.replace("/", "_")
        dst = os.path.join(OUT, name)
        os.makedirs(dst, exist_ok=True)
        with open(os.path.join(src, "truth.json")) as f:
            truth = json.load(f)
        n = int(SECONDS * truth["sample_rate"])
        fade = int(0.05 * truth["sample_rate"])
        ramp = np.linspace(1.0, 0.0, fade)
        for stem, mono in (("drums", True), ("mix", False)):
            x, sr = sf.read(os.path.join(src, f"{stem}.wav"), dtype="int16", always_2d=True)
            x = x[:n].astype(np.float64)
            x[-fade:] *= ramp[:, None]
            if mono:
                x = x.mean(axis=1, keepdims=True)
            sf.write(os.path.join(dst, f"{stem}.flac"), np.round(x).astype(np.int16), sr,
                     subtype="PCM_16")
        keep = {"format", "version", "song", "source", "family", "held_out", "kit", "style",
                "meter", "tempo_bpm", "sample_rate", "hop_s", "onsets_rule"}
        t = {k: v for k, v in truth.items() if k in keep}
        t["song"] = name
        t["duration_s"] = SECONDS
        t["audio_format"] = "flac"
        # Hits in the last 100 ms (under the fade) are dropped from the truth.
        t["onsets"] = {c: [h for h in hs if h["time_s"] < SECONDS - 0.1]
                       for c, hs in truth["onsets"].items()}
        t["f0_hz"] = {}
        with open(os.path.join(dst, "truth.json"), "w") as f:
            json.dump(t, f, indent=1)
        print(dst, {c: len(v) for c, v in t["onsets"].items()})


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Plain tones through `tactus render`: how often the finger a tone's stem drives is on it.

Sines, squares, saws and 808-style notes (a sine with 15 % second harmonic), 41.2 Hz to
2 kHz, held or gliding two semitones (the 2 kHz note down), 3 s at 44.1 kHz, alone
(the cases of tests/plain_tones.rs), over a drum loop (a pitched kick every second, a
snare on the off-second, hi-hats every 250 ms), or over the loop and a held triad of soft
saws a register away (C4 under a bass tone, C3 under a lead tone). The finger: the thumb
(bass) below the spectral separator's 250 Hz crossover, the ring (vocals) above.
Score: raw pitch accuracy (within 50 cents) over 0.3-2.7 s.

    V/bin/python benches/tones_eval.py --bin target/release/tactus \\
        [--background none,drums,drums+chords] [--supply] [--json OUT.json] [-- RENDER OPTIONS...]

With --supply the tone alone is also given as its finger's stem (`--stem bass=` or
`--stem vocals=`), as a clean stem from an ONNX separator or the user would be: the
recipes for clean stems.

Needs numpy. Prints one line per case and, per background, the mean and how many cases
reach 0.95.
"""
import argparse
import json
import math
import subprocess
import sys
import tempfile
import wave
from pathlib import Path

import numpy as np

SR = 44_100
SECONDS = 3.0
SCORED = (0.3, SECONDS - 0.3)


def f0_at(f0, glide, t):
    return f0 * 2 ** (np.clip(t - 1.0, 0.0, 1.0) * glide / 12)


def tone(kind, f0, glide):
    t = np.arange(int(SR * SECONDS)) / SR
    p = (np.cumsum(f0_at(f0, glide, t) / SR) % 1.0) * 2 * np.pi
    return 0.5 * {
        "sine": np.sin(p),
        "square": 0.6 * np.sign(np.sin(p)),
        "saw": 0.6 * (p / np.pi - 1),
        "808": 0.9 * (np.sin(p) + 0.15 * np.sin(2 * p)),
    }[kind]


def drum_loop():
    n = int(SR * SECONDS)
    x = np.zeros(n)
    rng = np.random.default_rng(1)
    for k, start in enumerate(np.arange(0, SECONDS, 0.25)):
        i = int(start * SR)
        m = min(n - i, int(0.3 * SR))
        tt = np.arange(m) / SR
        if k % 4 == 0:
            x[i:i + m] += 0.8 * np.sin(2 * np.pi * 60 * tt * (1 + np.exp(-tt / 0.03))) * np.exp(-tt / 0.08)
        if k % 4 == 2:
            x[i:i + m] += 0.5 * rng.standard_normal(m) * np.exp(-tt / 0.05)
            x[i:i + m] += 0.3 * np.sin(2 * np.pi * 190 * tt) * np.exp(-tt / 0.05)
        x[i:i + m] += 0.15 * rng.standard_normal(m) * np.exp(-tt / 0.01)
    return x


def triad(f0):
    t = np.arange(int(SR * SECONDS)) / SR
    root = 262.0 if f0 < 200 else 131.0
    x = np.zeros_like(t)
    for r in (1.0, 1.26, 1.5):
        ph = 2 * np.pi * root * r * t
        x += 0.12 * sum(np.sin(h * ph) / h for h in range(1, 6))
    return x


def write_wav(path, x):
    x = x / max(1.0, np.max(np.abs(x)) / 0.9)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(SR)
        w.writeframes((np.clip(x, -1, 1) * 32000).astype(np.int16).tobytes())


def cases():
    for kind in ("sine", "square", "saw", "808"):
        for f0 in (41.2, 55.0, 110.0, 220.0, 440.0, 1000.0, 2000.0):
            if kind == "808" and f0 > 220:
                continue
            for glide in (0.0, -2.0 if f0 >= 2000 else 2.0):
                yield kind, f0, glide


def rpa(features, stem, f0, glide):
    hop = features["hop_s"]
    ok = n = 0
    for i, p in enumerate(features["pitch_hz"][stem]):
        t = i * hop
        if not SCORED[0] <= t <= SCORED[1]:
            continue
        n += 1
        if p and p > 0 and abs(1200 * math.log2(p / f0_at(f0, glide, t))) < 50:
            ok += 1
    return ok / max(n, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--background", default="none,drums,drums+chords")
    ap.add_argument("--json")
    ap.add_argument("--supply", action="store_true",
                    help="give the tone alone as its finger's stem (--stem)")
    ap.add_argument("render", nargs="*", help="extra render options (after --)")
    a = ap.parse_args()
    loop = drum_loop()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for bg in a.background.split(","):
            for kind, f0, glide in cases():
                x = tone(kind, f0, glide)
                stem = "bass" if f0 < 250 else "vocals"
                supplied = []
                if a.supply:
                    write_wav(d / "stem.wav", x)
                    supplied = ["--stem", f"{stem}={d / 'stem.wav'}"]
                if "drums" in bg:
                    x = x + loop
                if "chords" in bg:
                    x = x + triad(f0)
                write_wav(d / "t.wav", x)
                r = subprocess.run(
                    [a.bin, "render", str(d / "t.wav"), "-o", str(d / "p.json"),
                     "--features", str(d / "f.json"), *supplied, *a.render],
                    capture_output=True, text=True)
                if r.returncode != 0:
                    sys.exit(f"render failed: {r.stderr}")
                score = rpa(json.loads((d / "f.json").read_text()), stem, f0, glide)
                rows.append(dict(background=bg, kind=kind, f0=f0, glide=glide, stem=stem, rpa=score))
                print(f"{bg:13s} {kind:6s} {f0:7.1f} Hz glide {glide:+.0f}  {stem:6s} {score:.3f}", flush=True)
    for bg in a.background.split(","):
        r = [x["rpa"] for x in rows if x["background"] == bg]
        print(f"{bg}: mean RPA {sum(r) / len(r):.3f}, {sum(v >= 0.95 for v in r)} of {len(r)} at 0.95 or more")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()

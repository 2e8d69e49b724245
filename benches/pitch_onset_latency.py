#!/usr/bin/env python3
"""How late a new note reaches the pitch cells, engine only (no sound server, no link).

Writes a 62 s stereo WAV of harmonic tone bursts (5 partials, 1/k, 5 ms raised-cosine
edges, 300 ms on, one per second, alternating 98 Hz and 392 Hz, each at a random offset
within 50 ms so that bursts fall anywhere on the hop grid), renders it with
    tactus render TONES.wav --profile live --mode streaming -o P.json [EXTRA...]
and, per burst, takes the first frame at or after its start whose pitch cell shows a level
(thumb cell 0 for 98 Hz; ring or pinky cell 0 for 392 Hz, whichever is first). In a
rendered pattern every feature sits at the time of its audio, so

    latency = end of that frame's bin − burst start + the pitch path's stated latency

where the stated latency (separator + denoise + tracker, samples at 44.1 kHz, as `tactus
live` prints it at exit, without the bin, which the first term holds) is what the live
glove waits on top. `benches/live_latency.py` measures the same bursts end to end, through
PulseAudio and a pty; this script isolates the engine's share and is deterministic.

    python3 benches/pitch_onset_latency.py [--tactus target/release/tactus]
        [--chain thumb=1331,ring=989,pinky=1178] [-- EXTRA RENDER ARGS]

The default --chain is the live profile's (two-frame YIN, 2026-11-24); for a build with
one YIN frame it was thumb=1601,ring=1145,pinky=1394.
"""

import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import wave

import numpy as np

RATE = 44100
CELLS = {"thumb": 0, "ring": 6, "pinky": 8}


def stimulus(path, seed=5):
    rng = random.Random(seed)
    sig = np.zeros(int(RATE * 62), dtype=np.float64)
    events = []
    t, i = 1.0, 0
    ramp = int(0.005 * RATE)
    n = int(0.3 * RATE)
    j = np.arange(n)
    g = np.ones(n)
    g[:ramp] = 0.5 - 0.5 * np.cos(np.pi * np.arange(ramp) / ramp)
    g[-ramp:] = 0.5 - 0.5 * np.cos(np.pi * (n - np.arange(n - ramp, n)) / ramp)
    while t < 60:
        f0 = 98.0 if i % 2 == 0 else 392.0
        start = int((t + rng.random() * 0.05) * RATE)
        v = sum(np.sin(2 * math.pi * f0 * k * j / RATE + rng.random() * 2 * math.pi) / k
                for k in range(1, 6))
        sig[start:start + n] += 0.3 * v * g
        events.append((start, f0))
        t += 1.0
        i += 1
    pcm = (np.clip(sig, -1, 1) * 32767).astype("<i2")
    with wave.open(path, "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(2)
        w.setframerate(RATE)
        w.writeframes(np.stack([pcm, pcm], axis=1).ravel().tobytes())
    return events


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tactus", default="target/release/tactus")
    ap.add_argument("--chain", default="thumb=1331,ring=989,pinky=1178",
                    help="stated latency of each pitch path without the bin, samples")
    ap.add_argument("extra", nargs="*")
    a = ap.parse_args()
    chain = {CELLS[k]: int(v) for k, v in (x.split("=") for x in a.chain.split(","))}
    with tempfile.TemporaryDirectory() as d:
        wav, pat = os.path.join(d, "tones.wav"), os.path.join(d, "p.json")
        events = stimulus(wav)
        subprocess.run([a.tactus, "render", wav, "--profile", "live", "--mode", "streaming",
                        "-o", pat] + a.extra, check=True, stderr=subprocess.DEVNULL)
        with open(pat) as fh:
            p = json.load(fh)
    frames = [bytes.fromhex(f) for f in p["frames"]]
    bin_ms = p["bin_ms"]
    res = {98.0: [], 392.0: []}
    for start, f0 in events:
        k0 = int(start * 1000 / RATE / bin_ms)
        best = None
        for cell in ([0] if f0 == 98.0 else [6, 8]):
            for k in range(k0, min(len(frames), k0 + int(900 / bin_ms))):
                if frames[k][cell]:
                    lat = (k + 1) * bin_ms - start * 1000 / RATE + chain[cell] * 1000 / RATE
                    best = lat if best is None else min(best, lat)
                    break
        res[f0].append(best)
    for f0, v in res.items():
        missed = sum(x is None for x in v)
        v = sorted(x for x in v if x is not None)
        if not v:
            print(f"{f0:5.0f} Hz: never shown")
            continue
        q = lambda f: v[min(len(v) - 1, int(math.ceil(len(v) * f)) - 1)]
        print(f"{f0:5.0f} Hz: {len(v)} shown, {missed} missed; median {q(0.5):.1f}, "
              f"p95 {q(0.95):.1f}, max {v[-1]:.1f} ms")


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Trains the spectral separator's low-band drum mask (crates/tactus-separate/src/lowband.rs)
and writes crates/tactus-separate/weights/lowband.bin.

Data: corpus songs with a known drum stem (DIR/<family>/<song>/{mix,drums}.wav, written by
corpus/drums.py), each in three variants: as mixed, with its kit 6 dB down, and without its
kit (every target 0, so a held low note alone is not a drum). Features and targets come
from the separator's own front end, dumped by
`cargo run --release -p tactus-engine --example lowband_features` (so training and inference
see the same numbers). Every VAL_EVERY-th song is kept for validation (early stopping).
Seeded: the same data and packages give the same weights (up to BLAS summation order).

    python3 models/lowband/train.py --data /work/data/i10drums --families timgm,csound,sonicpi,synth
    python3 models/lowband/train.py --init      # a zero model of the right shape (bootstrap)
Needs numpy only.
"""
import argparse
import glob
import os
import struct
import subprocess

import numpy as np

LOW, EDGES, PAST, FUTURE, OUT, SLOW = 24, [500.0, 1000.0, 2000.0, 4000.0, 8000.0, 16000.0], 6, 2, 15, 24
BIN_HZ = 44100.0 / 2048.0
PAD = -10.0
VAL_EVERY = 6
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DEFAULT_OUT = os.path.join(ROOT, "crates", "tactus-separate", "weights", "lowband.bin")
PER = LOW + len(EDGES) - 1 + SLOW


def write(path, w1, b1, w2, b2, past=PAST):
    hidden = w1.shape[1]
    head = b"TLBM" + struct.pack("<8I", 2, LOW, len(EDGES) - 1, past, FUTURE, hidden, OUT, SLOW)
    body = np.concatenate([[BIN_HZ], EDGES, w1.ravel(), b1, w2.ravel(), b2]).astype("<f4")
    tmp = path + ".tmp"
    with open(tmp, "wb") as fh:
        fh.write(head + body.tobytes())
    os.replace(tmp, path)


def dump(song, cache, gain, past=PAST):
    name = song.rstrip("/").split("/")[-2] + "_" + song.rstrip("/").split("/")[-1]
    p = os.path.join(cache, f"{name}.g{gain:g}.f32")
    if not os.path.exists(p):
        exe = os.path.join(ROOT, "target", "release", "examples", "lowband_features")
        subprocess.run([exe, os.path.join(song, "mix.wav"), os.path.join(song, "drums.wav"), p,
                        f"{gain:g}"], check=True)
    a = np.fromfile(p, dtype="<f4").reshape(-1, PER + 2 * OUT)
    f, y, m = a[:, :PER], a[:, PER:PER + OUT], a[:, PER + OUT:]
    t = len(f)
    # Before the start: PAD; after the end: the last frame repeated (as the separator does).
    fp = np.concatenate([np.full((past, PER), PAD, np.float32), f,
                         np.repeat(f[-1:], FUTURE, 0)])
    x = np.concatenate([fp[i:i + t] for i in range(past + 1 + FUTURE)], 1)  # oldest first
    w = np.sqrt(m / (m.max(1, keepdims=True) + 1e-9)) + 0.05
    return x, y, w


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="/work/data/i10drums")
    ap.add_argument("--families", default="timgm,csound,sonicpi,synth")
    ap.add_argument("--cache", default="/tmp/lowband-cache")
    ap.add_argument("--hidden", type=int, default=128)
    ap.add_argument("--past", type=int, default=PAST, help="context frames before the frame")
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--gains", default="1,0.5,0",
                    help="drum gains of each song's variants (0: the song without its kit)")
    ap.add_argument("--init", action="store_true", help="write a zero model and stop")
    a = ap.parse_args()
    h = a.hidden
    if a.init:
        ctx = a.past + 1 + FUTURE
        write(a.out, np.zeros((PER * ctx, h)), np.zeros(h), np.zeros((h, OUT)), np.full(OUT, -20.0),
              a.past)
        return
    os.makedirs(a.cache, exist_ok=True)
    songs = sorted(d for fam in a.families.split(",")
                   for d in glob.glob(os.path.join(a.data, fam, "*")) if os.path.isdir(d))
    val = songs[::VAL_EVERY]
    tr = [s for s in songs if s not in val]

    gains = [float(g) for g in a.gains.split(",")]

    def load(ss):
        parts = [dump(s, a.cache, g, a.past) for s in ss for g in gains]
        return [np.concatenate([p[i] for p in parts]) for i in range(3)]

    xt, yt, wt = load(tr)
    xv, yv, wv = load(val)
    mu, sd = xt.mean(0), xt.std(0) + 1e-3
    xt, xv = (xt - mu) / sd, (xv - mu) / sd
    rng = np.random.default_rng(a.seed)
    d = xt.shape[1]
    w1 = rng.normal(0, np.sqrt(2 / d), (d, h)).astype(np.float32)
    b1 = np.zeros(h, np.float32)
    w2 = rng.normal(0, np.sqrt(1 / h), (h, OUT)).astype(np.float32)
    b2 = np.zeros(OUT, np.float32)
    params = [w1, b1, w2, b2]
    m1 = [np.zeros_like(p) for p in params]
    m2 = [np.zeros_like(p) for p in params]
    lr, batch, step = 1e-3, 512, 0

    def fwd(x):
        hh = np.maximum(0, x @ w1 + b1)
        return hh, 1 / (1 + np.exp(-(hh @ w2 + b2)))

    print(f"train {xt.shape} ({len(tr)} songs), validation {xv.shape} ({len(val)} songs)", flush=True)
    best = (np.inf, None, -1)
    for ep in range(a.epochs):
        idx = rng.permutation(len(xt))
        for i in range(0, len(idx), batch):
            j = idx[i:i + batch]
            x, y, w = xt[j], yt[j], wt[j]
            hh, p = fwd(x)
            g = (p - y) * w / w.sum()
            gh = (g @ w2.T) * (hh > 0)
            grads = [x.T @ gh, gh.sum(0), hh.T @ g, g.sum(0)]
            step += 1
            for prm, gr, s1, s2 in zip(params, grads, m1, m2):
                s1 *= 0.9
                s1 += 0.1 * gr
                s2 *= 0.999
                s2 += 0.001 * gr * gr
                prm -= lr * (s1 / (1 - 0.9 ** step)) / (np.sqrt(s2 / (1 - 0.999 ** step)) + 1e-8)
        _, pv = fwd(xv)
        pv = np.clip(pv, 1e-6, 1 - 1e-6)
        bce = float((wv * -(yv * np.log(pv) + (1 - yv) * np.log(1 - pv))).sum() / wv.sum())
        mae = float((wv * np.abs(yv - pv)).sum() / wv.sum())
        print(f"epoch {ep:2d} validation BCE {bce:.4f} weighted MAE {mae:.4f}", flush=True)
        if bce < best[0]:
            best = (bce, [p.copy() for p in params], ep)
    bw1, bb1, bw2, bb2 = best[1]
    # Fold the standardisation into the first layer: (x - mu) / sd @ W1 + b1.
    fw1 = bw1 / sd[:, None]
    fb1 = bb1 - (mu / sd) @ bw1
    write(a.out, fw1, fb1, bw2, bb2, a.past)
    print(f"best epoch {best[2]} (validation BCE {best[0]:.4f}) -> {a.out}")


if __name__ == "__main__":
    main()

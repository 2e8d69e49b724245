#!/usr/bin/env python3
"""Trains the learned bass salience (`tactus_dsp::bassnet`) and writes its weight file.

Features are dumped by the render's own front end (`examples/bass_features.rs`: the default
spectral separator's bass stem, the bass chain's denoiser, decimator and frames), one
`.f32` file per song; targets are the songs' exact bass f0 (`truth.json`, 10 ms hops) on the
harmonic sum's candidate grid (35-400 Hz, 3 per semitone) plus a "no bass" class.

    cargo build --release -p tactus-engine --example bass_features
    python3 models/bassnet/train.py --train LIST --val LIST --features DIR \\
        --out crates/tactus-dsp/weights/bassnet.bin

LIST files hold one song folder per line. A song's features are `DIR/<tag>.f32`, where
<tag> is its path below /work/data (or its absolute path) with "/" replaced by "_"; missing
ones are dumped first with the example binary (`--bin`). numpy only; seeded: with
`OPENBLAS_NUM_THREADS=1` the same data give the same file.
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import time

import numpy as np

BPS = 3              # tactus_dsp::bassnet::BINS_PER_SEMITONE
RANGE_DB = 60.0      # ::RANGE_DB
# Per stem: front-end bands and band 0's centre (the bass's are tactus_dsp::bassnet::BANDS,
# LOW_HZ), the stem's pitch range (tactus_dsp::Stem::pitch_range_hz), the dumper's flags.
STEMS = {
    "bass": dict(bands=183, low_hz=30.0, fmin=35.0, fmax=400.0, truth="bass", flags=[]),
    # The harmonic-view bass model: the separator's vocals + bass + other as input.
    "bass_harm": dict(bands=183, low_hz=30.0, fmin=35.0, fmax=400.0, truth="bass",
                      flags=["--harmonic"]),
    "vocals": dict(bands=216, low_hz=70.0, fmin=70.0, fmax=1400.0, truth="vocals",
                   flags=["--lead", "216", "70"]),
    # The harmonic-view lead models: the separator's vocals + bass + other as input.
    "vocals_harm": dict(bands=216, low_hz=70.0, fmin=70.0, fmax=1400.0, truth="vocals",
                        flags=["--lead", "216", "70", "--harmonic"]),
    # The live profile's models: the live separator's harmonic sum on short frames
    # (tactus_engine::profile::LIVE_BASS_NET_FRAME_S, LIVE_LEAD_NET_FRAME_S).
    "bass_live": dict(bands=183, low_hz=30.0, fmin=35.0, fmax=400.0, truth="bass",
                      flags=["--live", "--harmonic", "--frame", "384"]),
    "vocals_live": dict(bands=216, low_hz=70.0, fmin=70.0, fmax=1400.0, truth="vocals",
                        flags=["--lead", "216", "70", "--live", "--harmonic", "--frame", "512"]),
}
BANDS, LOW_HZ, FMIN, FMAX, M, TRUTH, FLAGS = 183, 30.0, 35.0, 400.0, 127, "bass", []


def set_stem(name):
    global BANDS, LOW_HZ, FMIN, FMAX, M, TRUTH, FLAGS
    c = STEMS[name]
    BANDS, LOW_HZ, FMIN, FMAX = c["bands"], c["low_hz"], c["fmin"], c["fmax"]
    M = int(np.floor(12 * BPS * np.log2(FMAX / FMIN))) + 1
    TRUTH, FLAGS = c["truth"], c["flags"]


def tag_of(song):
    song = os.path.abspath(song.rstrip("/"))
    rel = song[len("/work/data/"):] if song.startswith("/work/data/") else song.lstrip("/")
    return rel.replace("/", "_")


def load(songs, feat_dir, binary, delay):
    """Per song: features [hops, BANDS] and labels [hops]: the true f0 in candidate bins
    (fractional), M = no bass; hop i's label is the truth at hop i - delay."""
    out = []
    for song in songs:
        path = os.path.join(feat_dir, tag_of(song) + ".f32")
        if not os.path.exists(path):
            mix = next(os.path.join(song, f"mix.{e}") for e in ("wav", "flac", "mp3", "ogg")
                       if os.path.exists(os.path.join(song, f"mix.{e}")))
            subprocess.run([binary, mix, path] + FLAGS, check=True)
        x = np.fromfile(path, dtype="<f4").reshape(-1, BANDS)
        f0 = json.load(open(os.path.join(song, "truth.json")))["f0_hz"][TRUTH]
        y = np.full(len(x), float(M))
        for i, f in enumerate(f0):
            # A negative delay asks the hop for the truth that many hops after it.
            if f and f > 0 and 0 <= i + delay < len(x):
                c = 12 * BPS * np.log2(f / FMIN)
                if -0.5 <= c < M - 0.5:
                    y[i + delay] = c
        out.append((x, y))
    return out


def context(x, offsets):
    """[hops, len(offsets)·BANDS]: the frames at the offsets, zeros outside the song."""
    n = len(x)
    parts = []
    for o in offsets:
        j = np.arange(n) + o
        ok = (j >= 0) & (j < n)
        part = np.zeros_like(x)
        part[ok] = x[j[ok]]
        parts.append(part)
    return np.concatenate(parts, 1)


def forward(P, x):
    h = x
    acts = [h]
    for i in range(0, len(P) - 2, 2):
        h = np.maximum(h @ P[i] + P[i + 1], 0)
        acts.append(h)
    return acts, h @ P[-2] + P[-1]


def log_softmax(z):
    z = z - z.max(1, keepdims=True)
    return z - np.log(np.exp(z).sum(1, keepdims=True))


def targets(y, sigma):
    """Soft targets: a Gaussian of `sigma` bins around the true (fractional) bin, or no bass."""
    T = np.zeros((len(y), M + 1), np.float32)
    v = y < M - 0.5
    c = np.arange(M)
    g = np.exp(-0.5 * ((c[None, :] - y[v][:, None]) / sigma) ** 2)
    T[v, :M] = g / g.sum(1, keepdims=True)
    T[~v, M] = 1
    return T


def write(path, P, offsets):
    b = bytearray(b"TACTUSBN")
    b += struct.pack("<III", 1, BANDS, BPS) + struct.pack("<ff", LOW_HZ, RANGE_DB)
    b += struct.pack("<I", len(offsets)) + struct.pack(f"<{len(offsets)}i", *offsets)
    b += struct.pack("<I", M) + struct.pack("<f", FMIN) + struct.pack("<I", len(P) // 2)
    for i in range(0, len(P), 2):
        w, bias = P[i], P[i + 1]
        b += struct.pack("<II", w.shape[0], w.shape[1])
        b += np.ascontiguousarray(w.T, dtype="<f4").tobytes() + np.asarray(bias, "<f4").tobytes()
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(bytes(b))
    os.replace(tmp, path)


def rpa_of(P, data, offsets):
    """Frame-wise argmax RPA (±50 cents) and voicing accuracy, a quick check."""
    hit = tot = vok = n = 0
    for x, y in data:
        _, z = forward(P, context(x, offsets))
        a = z.argmax(1)
        v = y < M - 0.5
        hit += int(np.sum(v & (a < M) & (np.abs(a - y) <= 1.5)))
        tot += int(v.sum())
        vok += int(np.sum((a < M) == v))
        n += len(y)
    return hit / max(tot, 1), vok / max(n, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stem", choices=sorted(STEMS), default="bass")
    ap.add_argument("--train", required=True)
    ap.add_argument("--val", default=None)
    ap.add_argument("--features", required=True)
    ap.add_argument("--bin", default="target/release/examples/bass_features")
    ap.add_argument("--out", required=True)
    ap.add_argument("--offsets", default="-8,-4,-2,0,2,4")
    ap.add_argument("--hidden", default="128,128")
    ap.add_argument("--epochs", type=int, default=10)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--sigma", type=float, default=1.0, help="target width, bins")
    ap.add_argument("--tilt", type=float, default=0.1, help="random spectral tilt (augmentation)")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--delay", type=int, default=3,
                    help="hops the targets lag the truth: the render moves the spectral "
                         "separator's bass track this many hops earlier "
                         "(tactus_engine::track::SPECTRAL_PITCH_ADVANCE_HOPS)")
    a = ap.parse_args()
    set_stem(a.stem)
    rng = np.random.default_rng(a.seed)
    offsets = [int(v) for v in a.offsets.split(",")]
    os.makedirs(a.features, exist_ok=True)
    read = lambda p: [s for s in open(p).read().split() if s]  # noqa: E731
    train = load(read(a.train), a.features, a.bin, a.delay)
    val = load(read(a.val), a.features, a.bin, a.delay) if a.val else []
    X = np.concatenate([context(x, offsets) for x, _ in train]).astype(np.float32)
    Y = np.concatenate([y for _, y in train])
    print(f"{len(train)} training songs, {len(X)} hops, {np.mean(Y < M - 0.5):.2f} voiced; "
          f"{len(offsets) * BANDS} inputs, {M + 1} outputs", flush=True)
    sizes = [X.shape[1]] + [int(h) for h in a.hidden.split(",")] + [M + 1]
    P = []
    for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:])):
        scale = np.sqrt((1.0 if i == len(sizes) - 2 else 2.0) / n_in)
        P += [rng.normal(0, scale, (n_in, n_out)).astype(np.float32), np.zeros(n_out, np.float32)]
    mom = [np.zeros_like(p) for p in P]
    vel = [np.zeros_like(p) for p in P]
    ramp = np.tile(np.linspace(-1, 1, BANDS, dtype=np.float32), len(offsets))[None, :]
    B, step = 256, 0
    for ep in range(a.epochs):
        t0, loss = time.time(), 0.0
        perm = rng.permutation(len(X))
        lr = a.lr * (1.0 - 0.9 * ep / max(1, a.epochs - 1))  # linear decay to a tenth
        for k in range(0, len(X) - B + 1, B):
            idx = perm[k:k + B]
            x = X[idx]
            # Augmentation: a kit or a bass recorded differently tilts the spectrum.
            x = np.clip(x + rng.uniform(-a.tilt, a.tilt, (B, 1)).astype(np.float32) * ramp * (x > 0), 0, 1)
            acts, z = forward(P, x)
            lp = log_softmax(z)
            T = targets(Y[idx], a.sigma)
            loss -= float((T * lp).sum()) / B
            g = (np.exp(lp) - T) / B
            grads = [None] * len(P)
            for i in range(len(P) - 2, -1, -2):
                grads[i] = acts[i // 2].T @ g
                grads[i + 1] = g.sum(0)
                if i:
                    g = (g @ P[i].T) * (acts[i // 2] > 0)
            step += 1
            for i, (p, gr) in enumerate(zip(P, grads)):
                mom[i] = 0.9 * mom[i] + 0.1 * gr
                vel[i] = 0.999 * vel[i] + 0.001 * gr * gr
                p -= lr * (mom[i] / (1 - 0.9 ** step)) / (np.sqrt(vel[i] / (1 - 0.999 ** step)) + 1e-8)
        msg = f"epoch {ep}: loss {loss / (len(X) // B):.3f}, {time.time() - t0:.0f} s"
        if val:
            r, v = rpa_of(P, val, offsets)
            msg += f"; validation frame-wise RPA {r:.3f}, voicing accuracy {v:.3f}"
        print(msg, flush=True)
    write(a.out, P, offsets)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    sys.exit(main())

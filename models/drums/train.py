#!/usr/bin/env python3
"""Trains the embedded drum transcriber's network (crates/tactus-dsp/src/drums.rs) and writes
it to --out. The embedded default (crates/tactus-dsp/weights/drums.bin) is this network
wrapped with its test-time retunings by models/drums/tta.py (Rebuild command in
models/drums/README.md); read_model reads both kinds of file.

Data: songs rendered by corpus/drums.py (DIR/<family>/<song>/{drums,mix}.wav + truth.json).
Features: the engine's own front end, dumped by
`cargo run --release -p tactus-engine --example drum_features` (so training and inference
see the same numbers). Three input conditions per song:
  iso  the drum stem alone;
  sep  the embedded spectral separator's drum stem of the mix (what `render` feeds it);
  mix  the mix itself.
Split: the HELD_OUT family (default musescore) is never used for training or tuning; of the
other families every VAL_EVERY-th song is kept for validation (threshold tuning, early
stopping). Everything is seeded: the same data and packages give the same weights (up to the
floating-point summation order of the machine's BLAS).

Usage:
  python3 models/drums/train.py --data /work/data/drums [--epochs 30] [--out PATH]
  python3 models/drums/train.py --data DIR --report-only   # score the committed weights
Needs numpy only.
"""
from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

CLASSES = ["kick", "snare", "toms", "cymbals"]
BANDS = 48
PAST, FUTURE = 7, 4
FLOOR = -16.0
LOG_FLOOR = float(np.log(np.float32(1e-20)))
HOP_S = 0.01
MIN_GAP = 5  # hops: ceil(0.05 s * 44100 / 441)
WINDOW_S = 0.05  # onset tolerance
HELD_OUT = ["fluid", "musescore"]  # musescore reuses FluidR3's drum samples: hold out both
VAL_EVERY = 4
CONDS = ["iso", "sep", "mix"]
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
DEFAULT_OUT = os.path.join(ROOT, "crates", "tactus-dsp", "weights", "drums.bin")


def dumper_path():
    return os.path.join(ROOT, "target", "release", "examples", "drum_features")


def features(song_dir, cond, cache):
    src = os.path.join(song_dir, "drums.wav" if cond.split("-")[0] == "iso" else "mix.wav")
    os.makedirs(os.path.dirname(cache), exist_ok=True)
    if not os.path.exists(cache) or os.path.getmtime(cache) < os.path.getmtime(src):
        tmp = f"{cache}.{os.getpid()}.{threading.get_ident()}.tmp"
        subprocess.run([dumper_path(), src, tmp, cond], check=True)
        os.replace(tmp, cache)
    return np.fromfile(cache, dtype="<f4").reshape(-1, BANDS)


WHITEN = 0.0  # --whiten: time constant of the per-band running mean, in hops (0: none)
WHITEN_EPS = 1e-20  # power floor of the running mean (the front end's LOG_FLOOR)


def whiten(mel):
    """Adaptive whitening, causal, as drums.rs does (file version 3): every log mel band
    minus the log of a running mean of that band's power (exp of the log mel value),
    m[j] = a m[j-1] + (1 - a) p[j] with a = exp(-1 / WHITEN), started at m[-1] = 0 and
    divided by 1 - a^(j+1) (the plain mean of the frames so far until the exponential
    window fills), in f64:  out[j] = mel[j] - ln(m[j] / (1 - a^(j+1)) + WHITEN_EPS).
    A kit's fixed colouring and the backing's steady spectrum drop out; the window
    normalisation of context() follows."""
    if WHITEN <= 0:
        return mel
    a = np.exp(-1.0 / WHITEN)
    p = np.exp(mel.astype(np.float64))
    n = p.shape[0]
    out = np.empty_like(p)
    state = np.zeros(p.shape[1])
    blk = 256  # a^-k stays far from overflow within a block
    for s in range(0, n, blk):
        q = p[s:s + blk]
        k = np.arange(q.shape[0], dtype=np.float64)[:, None]
        acc = np.cumsum(q * a ** (-k), axis=0) * a ** k * (1 - a)
        m = a ** (k + 1) * state + acc
        state = m[-1]
        corr = 1.0 - a ** (s + k + 1)
        out[s:s + blk] = m / corr
    return (mel.astype(np.float64) - np.log(out + WHITEN_EPS)).astype(np.float32)


BACK = False  # --backing: a second view, the separator's backing (bass + vocals + other)
CEIL = 6.0  # the backing view's ceiling over the drum window's maximum, nepers


def prep(mel):
    """Network inputs before standardisation: whitening (if any), then the context. With
    BACK, mel holds the drum view's BANDS columns and then the backing's; the backing's
    context is normalised by the drum window's maximum and clipped to [FLOOR, CEIL]. With
    SHORT, the second BANDS columns are the short view (the 1024-point frames), whose
    context is normalised by its own window's maximum, as drums.rs does (feature set 3)."""
    if SHORT:
        return np.concatenate([context(mel[:, :BANDS]), context(mel[:, BANDS:])], axis=1)
    if not BACK:
        return context(whiten(mel))
    d, b = mel[:, :BANDS], mel[:, BANDS:]
    xd = context(whiten(d), raw=True)
    xb = context(b, raw=True)
    m = xd.max(axis=1, keepdims=True)
    xd = np.maximum(xd - m, np.float32(FLOOR))
    xb = np.clip(xb - m, np.float32(FLOOR), np.float32(CEIL))
    return np.concatenate([xd, xb], axis=1).astype(np.float32)


def context(mel, raw=False):
    """Network inputs for every hop: frames i-PAST..i+FUTURE, normalised as in drums.rs
    (raw: not normalised)."""
    n = mel.shape[0]
    pad_before = np.full((PAST, BANDS), LOG_FLOOR, np.float32)
    last = mel[-1:] if n else np.full((1, BANDS), LOG_FLOOR, np.float32)
    pad_after = np.repeat(last, FUTURE, axis=0)
    m = np.concatenate([pad_before, mel, pad_after]).astype(np.float32)
    win = PAST + 1 + FUTURE
    idx = np.arange(n)[:, None] + np.arange(win)[None, :]
    x = m[idx].reshape(n, win * BANDS)
    if raw:
        return x
    x = np.maximum(x - x.max(axis=1, keepdims=True), np.float32(FLOOR))
    return x.astype(np.float32)


def labels(truth, n, hard_neg=1.0, ghost=1.0):
    """Targets and weights per hop. hard_neg > 1: a class's negative at another class's
    onset (+-1 hop), e.g. toms on a snare hit, weighs hard_neg (the confusions that
    differ most between kits). ghost != 1: a ghost snare's positive (velocity <= GHOST_VEL)
    weighs ghost."""
    y = np.zeros((n, 4), np.float32)
    w = np.ones((n, 4), np.float32)
    for c, name in enumerate(CLASSES):
        for hit in truth.get("onsets", {}).get(name, []):
            i = int(round(hit["time_s"] / HOP_S))
            for d in (-1, 1):
                if 0 <= i + d < n and y[i + d, c] == 0:
                    w[i + d, c] = 0.0
            if 0 <= i < n:
                quiet = name == "snare" and hit.get("velocity", 127) <= GHOST_VEL
                weight = ghost if quiet else 1.0
                # Two hits on one hop: the larger weight.
                w[i, c] = max(w[i, c], weight) if y[i, c] else weight
                y[i, c] = 1.0
    if hard_neg != 1.0:
        near = y.copy()
        near[1:] = np.maximum(near[1:], y[:-1])
        near[:-1] = np.maximum(near[:-1], y[1:])
        for c in range(4):
            other = np.delete(near, c, axis=1).max(axis=1) > 0
            sel = other & (y[:, c] == 0) & (w[:, c] > 0)
            w[sel, c] *= hard_neg
    return y, w


GHOST_VEL = 45  # the bench's ghost-snare bound (benches/drums_eval.py, "Recall by hit type")

# --aux: finer kinds of hit, learnt beside the four classes by extra outputs that only
# training sees (the written model keeps the four class outputs). Each kind is a set of GM
# notes and, for the snare, a velocity range; a kind's target is 1 on the hop of any of its
# hits (truth.json "hits", every MIDI hit), unweighted on the hops beside it.
AUX_KINDS = [
    ("closed hat", (42, 44), None),
    ("open hat", (46,), None),
    ("ride", (51, 53, 59), None),
    ("crash-like", (49, 52, 55, 57), None),
    ("backbeat snare", (38, 40), (GHOST_VEL + 1, 127)),
    ("ghost snare", (38, 40), (0, GHOST_VEL)),
    ("rim", (37,), None),
    ("low tom", (41, 43, 45), None),
    ("high tom", (47, 48, 50), None),
]


def aux_labels(truth, n):
    """Targets and weights of the AUX_KINDS per hop, as labels() makes the classes'."""
    y = np.zeros((n, len(AUX_KINDS)), np.float32)
    w = np.ones((n, len(AUX_KINDS)), np.float32)
    for k, (_, notes, vel) in enumerate(AUX_KINDS):
        for hit in truth.get("hits", []):
            v = hit.get("velocity", 127)
            if hit["note"] not in notes or (vel and not vel[0] <= v <= vel[1]):
                continue
            i = int(round(hit["time_s"] / HOP_S))
            for d in (-1, 1):
                if 0 <= i + d < n and y[i + d, k] == 0:
                    w[i + d, k] = 0.0
            if 0 <= i < n:
                y[i, k] = 1.0
                w[i, k] = 1.0
    return y, w


def songs(data):
    out = []
    for fam in sorted(os.listdir(data)):
        fd = os.path.join(data, fam)
        if not os.path.isdir(fd):
            continue
        for s in sorted(os.listdir(fd)):
            sd = os.path.join(fd, s)
            if os.path.exists(os.path.join(sd, "truth.json")) and os.path.exists(
                os.path.join(sd, "mix.wav")
            ):
                out.append((fam, s, sd))
    return out


def split(items):
    tr, va, ho = [], [], []
    per_fam = {}
    for fam, s, sd in items:
        if fam in HELD_OUT:
            ho.append((fam, s, sd))
            continue
        if fam in ("choke", "choke2") and s.split("-", 1)[0] in HELD_OUT:
            continue  # a `choke` song is made of its source family's sounds (corpus/drums.py)
        k = per_fam.get(fam, 0)
        per_fam[fam] = k + 1
        (va if k % VAL_EVERY == VAL_EVERY - 1 else tr).append((fam, s, sd))
    return tr, va, ho


def load(items, data, conds):
    jobs = [(it, c) for it in items for c in conds]

    def one(job):
        (fam, s, sd), c = job
        mel = features(sd, c, os.path.join(data, ".features", fam, f"{s}.{c}.f32"))
        if SHORT:
            sh = features(sd, f"{c}-short", os.path.join(data, ".features", fam, f"{s}.{c}-short.f32"))
            n = min(len(mel), len(sh))
            mel = np.concatenate([mel[:n], sh[:n]], axis=1)
        if BACK:
            if c == "sep":
                back = features(sd, "back", os.path.join(data, ".features", fam, f"{s}.back.f32"))
                n = min(len(mel), len(back))
                mel = np.concatenate([mel[:n], back[:n]], axis=1)
            else:
                mel = np.concatenate([mel, np.full_like(mel, LOG_FLOOR)], axis=1)
        with open(os.path.join(sd, "truth.json")) as f:
            truth = json.load(f)
        return (fam, s, c, mel, truth)

    with ThreadPoolExecutor(2) as ex:
        return list(ex.map(one, jobs))


# ---------------------------------------------------------------- the network (numpy)
def init(sizes, rng):
    ps = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        ps.append([(rng.standard_normal((b, a)) * np.sqrt(2.0 / a)).astype(np.float32),
                   np.zeros(b, np.float32)])
    ps[-1][1][:] = -3.0  # onsets are rare
    return ps


def forward(ps, x, drop=0.0, rng=None):
    """Every layer's output (the input first). drop > 0 (training only): inverted dropout
    on the hidden layers' outputs, each unit kept with probability 1 - drop and scaled by
    1 / (1 - drop)."""
    acts = [x]
    h = x
    for li, (W, b) in enumerate(ps):
        z = h @ W.T + b
        h = z if li == len(ps) - 1 else np.maximum(z, 0)
        if drop > 0 and li < len(ps) - 1:
            h = h * ((rng.random(h.shape, np.float32) >= drop) / np.float32(1 - drop))
        acts.append(h)
    return acts


def sigmoid(z):
    return 1.0 / (1.0 + np.exp(-np.clip(z, -40, 40)))


SHIFT = 2  # mel bands, --shift
WARP = 1.0  # --warp: largest retuning ratio (1: none)
STRETCH = 1.0  # --stretch: largest time-scale ratio of the context (1: none)
FLUX = False  # --flux: append the positive first difference of the normalised frames
SHORT = False  # --short: a second view, the 1024-point frames (input feature set 3)
F_LO, F_HI = 20.0, 16_000.0  # MelConfig::drums


def _mel(f):
    return 2595.0 * np.log10(1.0 + np.asarray(f) / 700.0)


def _hz(m):
    return 700.0 * (10.0 ** (np.asarray(m) / 2595.0) - 1.0)


def _gather(z, pos, axis):
    """Linear interpolation of z along axis (1: frames, 2: bands) at fractional positions
    pos (batch, n), clamped to the edges."""
    n = z.shape[axis]
    pos = np.clip(pos, 0, n - 1)
    i0 = np.floor(pos).astype(np.int64)
    i1 = np.minimum(i0 + 1, n - 1)
    fr = (pos - i0).astype(np.float32)
    if axis == 2:
        a = np.take_along_axis(z, i0[:, None, :], 2)
        b = np.take_along_axis(z, i1[:, None, :], 2)
        return a + (b - a) * fr[:, None, :]
    a = np.take_along_axis(z, i0[:, :, None], 1)
    b = np.take_along_axis(z, i1[:, :, None], 1)
    return a + (b - a) * fr[:, :, None]


def retune(z, rng):
    """Each example's kit retuned by a ratio in [1/WARP, WARP] (log-uniform): band b takes
    the value at frequency centre_b / ratio (a shift of a fraction of a band at the low
    end, where mel is nearly linear, a few bands at the top), and its context stretched in
    time around the current frame by [1/STRETCH, STRETCH] (shorter or longer decays)."""
    b, win, width = z.shape
    if WARP > 1.0:
        m = np.linspace(_mel(F_LO), _mel(F_HI), BANDS + 2)[1:-1]
        r = np.exp(rng.uniform(-np.log(WARP), np.log(WARP), (b, 1)))
        src = np.interp(_mel(_hz(m)[None, :] / r), m, np.arange(BANDS, dtype=np.float64))
        if width == BANDS:
            z = _gather(z, src, 2)
        else:  # views side by side (SHORT): the same retuning of each
            z = np.concatenate([_gather(z[:, :, v:v + BANDS], src, 2)
                                for v in range(0, width, BANDS)], axis=2)
    if STRETCH > 1.0:
        s = np.exp(rng.uniform(-np.log(STRETCH), np.log(STRETCH), (b, 1)))
        t = np.arange(win, dtype=np.float64)[None, :]
        z = _gather(z, PAST + (t - PAST) / s, 1)
    return z


EQ_SCALE = 1.0  # --eq-scale: the tilt's and bumps' range times this (1: about +-6 dB)


def eq_draw(rng, b):
    """One random spectral tilt and smooth EQ per example (about +-6 dB over the bands, times
    EQ_SCALE): (tilt, bumps), each (b, 1, BANDS), to be added to log mel frames."""
    pos = np.linspace(-1, 1, BANDS, dtype=np.float32)
    tilt = rng.uniform(-1.4, 1.4, (b, 1, 1)).astype(np.float32) * pos
    bumps = sum(rng.uniform(-0.7, 0.7, (b, 1, 1)).astype(np.float32)
                * np.cos(np.pi * k * (pos + 1) / 2) for k in (2, 3, 4))
    if EQ_SCALE != 1.0:
        tilt, bumps = tilt * np.float32(EQ_SCALE), bumps * np.float32(EQ_SCALE)
    return tilt, bumps


FMASK = 0  # --freq-mask: the widest band range silenced in an example (0: none)
FMASK_P = 0.5  # the fraction of examples masked


def freq_mask(z, rng):
    """Frequency masking (SpecAugment): in a fraction FMASK_P of the examples (b, frames,
    BANDS) a range of 1..FMASK adjacent mel bands, the same in every frame, is silenced
    (set 40 nepers below the example's maximum, under the floor once normalised), as if
    the kit had nothing there: the network may not lean on any one band range alone."""
    b = z.shape[0]
    width = rng.integers(1, FMASK + 1, b)
    lo = rng.integers(0, BANDS - width + 1)
    on = rng.random(b) < FMASK_P
    k = np.arange(BANDS)[None, :]
    mask = on[:, None] & (k >= lo[:, None]) & (k < (lo + width)[:, None])
    low = z.max(axis=(1, 2)) - 40.0
    return np.where(mask[:, None, :], low[:, None, None].astype(np.float32), z)


def augment(x, rng):
    """Kit-to-kit variation in feature space: a random spectral tilt and smooth EQ
    (+-6 dB), a shift of +-SHIFT mel bands (drums tuned differently), then the window
    normalisation of drums.rs again. With SHORT, both views get the same retuning,
    stretch and EQ (one draw per example), each normalised by its own maximum."""
    b = x.shape[0]
    if SHORT:
        half = x.shape[1] // 2
        win = half // BANDS
        z = np.concatenate([x[:, :half].reshape(b, win, BANDS), x[:, half:].reshape(b, win, BANDS)], axis=2)
        z = retune(z, rng)  # both views, one draw per example
        tilt, bumps = eq_draw(rng, b)
        out = []
        for v in range(2):
            zz = (z[:, :, v * BANDS:(v + 1) * BANDS] + tilt + bumps).reshape(b, -1)
            out.append(np.maximum(zz - zz.max(axis=1, keepdims=True), np.float32(FLOOR)))
        return np.concatenate(out, axis=1)
    xb = None
    if BACK:
        half = x.shape[1] // 2
        x, xb = x[:, :half], x[:, half:].reshape(b, -1, BANDS)
    win = x.shape[1] // BANDS
    z = x.reshape(b, win, BANDS).copy()
    z = retune(z, rng)
    shift = rng.integers(-SHIFT, SHIFT + 1)
    if shift > 0:
        z[:, :, shift:] = z[:, :, :-shift].copy()
    elif shift < 0:
        z[:, :, :shift] = z[:, :, -shift:].copy()
    tilt, bumps = eq_draw(rng, b)
    z = z + tilt + bumps
    if FMASK > 0:
        z = freq_mask(z, rng)
    z = z.reshape(b, -1)
    m = z.max(axis=1, keepdims=True)
    z = np.maximum(z - m, np.float32(FLOOR))
    if xb is None:
        return z
    # The backing: the same EQ, then the drum window's new maximum; floor-level bins stay
    # at the floor.
    floor = xb <= FLOOR + 1e-6
    zb = (xb + tilt + bumps).reshape(b, -1) - m
    zb = np.clip(zb, np.float32(FLOOR), np.float32(CEIL))
    zb[floor.reshape(b, -1)] = np.float32(FLOOR)
    return np.concatenate([z, zb], axis=1)


def with_flux(x):
    """Network input from normalised contexts x (n, win*BANDS): x itself and, with FLUX, the
    positive first difference of consecutive frames (n, (win-1)*BANDS), as drums.rs does."""
    if not FLUX:
        return x
    z = x.reshape(x.shape[0], -1, BANDS)
    d = np.maximum(z[:, 1:] - z[:, :-1], 0).reshape(x.shape[0], -1)
    return np.concatenate([x, d], axis=1)


def near_onset(Y, reach=3):
    """Frames within +-reach hops of an onset of any class."""
    any_ = Y.max(axis=1) > 0
    near = any_.copy()
    for d in range(1, reach + 1):
        near[d:] |= any_[:-d]
        near[:-d] |= any_[d:]
    return near


def superpose(x, y, w, X, Y, W, pool, rng, p):
    """Superposition augmentation: a fraction p of the batch's examples each get a window
    from near another onset (pool: indices into X) added in power, its peak SUPER_DB below
    to above the example's own (both windows are normalised to a maximum of 0, in nepers of
    power), then the window normalisation again. Targets are the union; a positive keeps
    the larger weight, a negative the smaller (so the unweighted hops beside an onset stay
    unweighted). Real kits sound together; this teaches the sum, not only the parts."""
    sel = np.flatnonzero(rng.random(len(x)) < p)
    if len(sel) == 0:
        return x, y, w
    j = pool[rng.integers(0, len(pool), len(sel))]
    lo, hi = (d / (10.0 / np.log(10.0)) for d in SUPER_DB)
    g = rng.uniform(lo, hi, (len(sel), 1)).astype(np.float32)
    x, y, w = x.copy(), y.copy(), w.copy()
    z = np.logaddexp(x[sel], X[j] + g)
    x[sel] = np.maximum(z - z.max(axis=1, keepdims=True), np.float32(FLOOR))
    ya, yb, wa, wb = y[sel], Y[j], w[sel], W[j]
    pos = np.maximum(ya, yb)
    wpos = np.maximum(wa * ya, wb * yb)
    w[sel] = np.where(pos > 0, wpos, np.minimum(wa, wb))
    y[sel] = pos
    return x, y, w


SUPER_DB = (-20.0, 5.0)  # --superpose: the added window's peak relative to the example's


def train(ps, X, Y, W, Xv, Yv, Wv, epochs, rng, lr=1e-3, batch=512, pos_weight=None,
          mean=None, std=None, aug=True, decay=1e-5, neg_keep=1.0, in_drop=0.0, sup=0.0,
          drop=0.0, swa=0.0):
    """Adam on weighted binary cross-entropy. swa > 0: return the mean of the weights at
    the end of every epoch from epochs * swa on (weight averaging) instead of the epoch with
    the lowest validation loss. neg_keep < 1: each epoch uses every frame
    near an onset (+-3 hops) and a fresh random fraction neg_keep of the others, weighted
    1 / neg_keep (the same expected loss, fewer frames per epoch). sup > 0: the
    superposition augmentation (superpose) on that fraction of each batch."""
    m = [[np.zeros_like(W_), np.zeros_like(b_)] for W_, b_ in ps]
    v = [[np.zeros_like(W_), np.zeros_like(b_)] for W_, b_ in ps]
    t = 0
    best = (np.inf, None)
    avg, n_avg = None, 0
    near = near_onset(Y)
    near_idx, far_idx = np.flatnonzero(near), np.flatnonzero(~near)
    pw = np.asarray(pos_weight if pos_weight is not None else 1.0, np.float32)
    for ep in range(epochs):
        if neg_keep < 1.0:
            keep = far_idx[rng.random(len(far_idx)) < neg_keep]
            order = rng.permutation(np.concatenate([near_idx, keep]))
        else:
            order = rng.permutation(X.shape[0])
        n = len(order)
        tot = 0.0
        for s in range(0, n, batch):
            idx = order[s:s + batch]
            x, y, w = X[idx], Y[idx], W[idx]
            if neg_keep < 1.0:
                w = w * np.where(near[idx], 1.0, 1.0 / neg_keep).astype(np.float32)[:, None]
            if sup > 0:
                x, y, w = superpose(x, y, w, X, Y, W, near_idx, rng, sup)
            if aug:
                x = augment(x, rng)
            x = (with_flux(x) - mean) / std
            if in_drop > 0:  # input dropout: a standardised input set to its mean
                x = x * ((rng.random(x.shape, np.float32) >= in_drop) / np.float32(1 - in_drop))
            acts = forward(ps, x, drop, rng)
            p = sigmoid(acts[-1])
            ww = w * (1 + (pw - 1) * y)
            g = (p - y) * ww / len(idx)
            tot += float(-(ww * (y * np.log(p + 1e-7) + (1 - y) * np.log(1 - p + 1e-7))).sum())
            t += 1
            for li in range(len(ps) - 1, -1, -1):
                Wl, bl = ps[li]
                gW = g.T @ acts[li] + decay * Wl
                gb = g.sum(0)
                if li > 0:
                    g = (g @ Wl) * (acts[li] > 0)
                    if drop > 0:  # the kept units' 1 / (1 - drop)
                        g = g / np.float32(1 - drop)
                for k, gr in enumerate((gW, gb)):
                    m[li][k] = 0.9 * m[li][k] + 0.1 * gr
                    v[li][k] = 0.999 * v[li][k] + 0.001 * gr * gr
                    mh = m[li][k] / (1 - 0.9 ** t)
                    vh = v[li][k] / (1 - 0.999 ** t)
                    ps[li][k] -= (lr * mh / (np.sqrt(vh) + 1e-8)).astype(np.float32)
        # Early stopping on the four classes alone (--aux outputs are training's only).
        pv = sigmoid(forward(ps, (with_flux(Xv) - mean) / std)[-1])[:, :4]
        yv, wv = Yv[:, :4], Wv[:, :4]
        pw4 = pw[:4] if pw.ndim else pw
        ww = wv * (1 + (pw4 - 1) * yv)
        vl = float(-(ww * (yv * np.log(pv + 1e-7) + (1 - yv) * np.log(1 - pv + 1e-7))).sum() / len(Xv))
        print(f"epoch {ep + 1}: train {tot / n:.4f} val {vl:.4f}", flush=True)
        if vl < best[0]:
            best = (vl, [[W_.copy(), b_.copy()] for W_, b_ in ps])
        if swa > 0 and ep >= int(epochs * swa):
            n_avg += 1
            if avg is None:
                avg = [[W_.astype(np.float64), b_.astype(np.float64)] for W_, b_ in ps]
            else:
                for (aW, ab), (W_, b_) in zip(avg, ps):
                    aW += (W_ - aW) / n_avg
                    ab += (b_ - ab) / n_avg
        if ep == int(epochs * 0.7):
            lr *= 0.3
    if avg is not None:
        return [[aW.astype(np.float32), ab.astype(np.float32)] for aW, ab in avg]
    return best[1]


# ---------------------------------------------------------------- peak picking + scoring
def pick(a, thr):
    """drums.rs Picker, per class: returns hop indices."""
    out = []
    armed, peak, last = True, 0.0, None
    for i, x in enumerate(a):
        if not armed:
            peak = max(peak, x)
            if x < thr or x < 0.5 * peak:
                armed = True
        if armed and x >= thr and (last is None or i - last >= MIN_GAP):
            armed, peak, last = False, x, i
            out.append(i)
    return out


def match(est, ref, tol=WINDOW_S):
    """Greedy one-to-one matching in time order (mir_eval-like for sorted lists)."""
    est, ref = sorted(est), sorted(ref)
    used = [False] * len(ref)
    tp = 0
    j0 = 0
    for e in est:
        while j0 < len(ref) and ref[j0] < e - tol:
            j0 += 1
        j = j0
        while j < len(ref) and ref[j] <= e + tol:
            if not used[j]:
                used[j] = True
                tp += 1
                break
            j += 1
    return tp, len(est) - tp, len(ref) - tp


def prf(tp, fp, fn):
    p = tp / (tp + fp) if tp + fp else 0.0
    r = tp / (tp + fn) if tp + fn else 0.0
    f = 2 * p * r / (p + r) if p + r else 0.0
    return p, r, f


def score(acts_list, truths, thr):
    res = []
    for c, name in enumerate(CLASSES):
        T = [0, 0, 0]
        for a, truth in zip(acts_list, truths):
            est = [i * HOP_S for i in pick(a[:, c], thr[c])]
            ref = [h["time_s"] for h in truth.get("onsets", {}).get(name, [])]
            for k, v in enumerate(match(est, ref)):
                T[k] += v
        res.append(prf(*T) + tuple(T))
    return res


def tune(acts_list, truths):
    thr = []
    for c in range(4):
        best = (-1, 0.5)
        for t in np.arange(0.1, 0.95, 0.025):
            th = [0.5] * 4
            th[c] = t
            f = score(acts_list, truths, th)[c][2]
            if f > best[0]:
                best = (f, float(t))
        thr.append(best[1])
    return thr


# ---------------------------------------------------------------- file format
def write_model(path, ps, mean, std, thr):
    # Fold the standardisation (x - mean) / std into the first layer.
    W0, b0 = ps[0]
    W0f = W0 / std[None, :]
    b0f = b0 - W0f @ mean
    layers = [(W0f, b0f)] + [(W, b) for W, b in ps[1:]]
    with open(path + ".tmp", "wb") as f:
        f.write(b"TACTUSDR")
        if WHITEN > 0:  # version 3: the feature set, then the whitening time constant (hops)
            f.write(struct.pack("<6I", 3, BANDS, PAST, FUTURE, 4, len(layers)))
            f.write(struct.pack("<f", FLOOR))
            f.write(struct.pack("<I", 1 if FLUX else 0))
            f.write(struct.pack("<f", WHITEN))
        elif SHORT:  # version 2 with feature set 3: mel + the short view's mel
            f.write(struct.pack("<6I", 2, BANDS, PAST, FUTURE, 4, len(layers)))
            f.write(struct.pack("<f", FLOOR))
            f.write(struct.pack("<I", 3))
        elif BACK:  # version 2 with feature set 2: mel + the backing's mel, then CEIL
            f.write(struct.pack("<6I", 2, BANDS, PAST, FUTURE, 4, len(layers)))
            f.write(struct.pack("<f", FLOOR))
            f.write(struct.pack("<I", 2))
            f.write(struct.pack("<f", CEIL))
        elif FLUX:  # version 2: a u32 input-feature set follows the floor (1: mel + flux)
            f.write(struct.pack("<6I", 2, BANDS, PAST, FUTURE, 4, len(layers)))
            f.write(struct.pack("<f", FLOOR))
            f.write(struct.pack("<I", 1))
        else:
            f.write(struct.pack("<6I", 1, BANDS, PAST, FUTURE, 4, len(layers)))
            f.write(struct.pack("<f", FLOOR))
        for W, b in layers:
            f.write(struct.pack("<2I", W.shape[1], W.shape[0]))
            f.write(np.ascontiguousarray(W, dtype="<f4").tobytes())
            f.write(np.ascontiguousarray(b, dtype="<f4").tobytes())
        f.write(np.asarray(thr, dtype="<f4").tobytes())
    os.replace(path + ".tmp", path)


RATIOS = [1.0]  # test-time retunings of the file read last ("TACTUSDT", tta.py); [1.0]: none


def read_model(path):
    """(network parameters, thresholds) of a model file; sets the feature globals (and
    RATIOS for a retuned file, whose thresholds are the averaged activations')."""
    global RATIOS
    with open(path, "rb") as f:
        buf = f.read()
    RATIOS = [1.0]
    if buf[:8] == b"TACTUSD2":  # a second stage around a model file (stage2/stage2.py)
        ver, _, _, _, mask = struct.unpack_from("<2I2fI", buf, 8)
        off = 28
        for _ in range(bin(mask).count("1")):  # skip the judges
            if ver == 1:
                off += 44
                continue
            (h,) = struct.unpack_from("<I", buf, off)
            off += 4 + (44 if h == 0 else 4 * (12 * h + 2))
        (ln,) = struct.unpack_from("<I", buf, off)
        buf = buf[off + 4:off + 4 + ln]
    if buf[:8] == b"TACTUSDT":
        _, n = struct.unpack_from("<2I", buf, 8)
        ratios = [float(r) for r in np.frombuffer(buf, "<f4", n, 16)]
        (ln,) = struct.unpack_from("<I", buf, 16 + 4 * n)
        start = 20 + 4 * n
        ps, _ = read_model_bytes(buf[start:start + ln])
        RATIOS = ratios
        return ps, list(np.frombuffer(buf, "<f4", 4, start + ln))
    return read_model_bytes(buf)


def read_model_bytes(buf):
    assert buf[:8] == b"TACTUSDR"
    ver, bands, past, fut, ncls, nl = struct.unpack_from("<6I", buf, 8)
    (floor,) = struct.unpack_from("<f", buf, 32)
    off = 36
    global FLUX, WHITEN, PAST, FUTURE, BACK, CEIL, SHORT
    FLUX, WHITEN, PAST, FUTURE, BACK, SHORT = False, 0.0, past, fut, False, False
    if ver >= 2:
        (feat,) = struct.unpack_from("<I", buf, off)
        off += 4
        FLUX = feat == 1
        BACK = feat == 2
        SHORT = feat == 3
        if BACK:
            (CEIL,) = struct.unpack_from("<f", buf, off)
            off += 4
    if ver >= 3:
        (WHITEN,) = struct.unpack_from("<f", buf, off)
        off += 4
    ps = []
    for _ in range(nl):
        ni, no = struct.unpack_from("<2I", buf, off)
        off += 8
        W = np.frombuffer(buf, "<f4", ni * no, off).reshape(no, ni)
        off += 4 * ni * no
        b = np.frombuffer(buf, "<f4", no, off)
        off += 4 * no
        ps.append([W, b])
    thr = list(np.frombuffer(buf, "<f4", 4, off))
    return ps, thr


def retuned(x, ratio):
    """Normalised windows x (n, frames * BANDS) with the mel axis retuned by ratio (band b
    takes the value at frequency centre_b / ratio, linear between bands), normalised again:
    drums.rs `Retuning::apply`."""
    if ratio == 1.0:
        return x
    n = x.shape[0]
    m = np.linspace(_mel(F_LO), _mel(F_HI), BANDS + 2)[1:-1]
    src = np.interp(_mel(_hz(m) / ratio), m, np.arange(BANDS, dtype=np.float64))
    z = _gather(x.reshape(n, -1, BANDS), np.repeat(src[None, :], n, 0), 2).reshape(n, -1)
    return np.maximum(z - z.max(axis=1, keepdims=True), np.float32(FLOOR))


def activations(ps, mel, ratios=None):
    """Per-hop activations; with test-time retunings (default: RATIOS, those of the file
    read last) the mean over the retuned windows, as drums.rs computes them."""
    ratios = RATIOS if ratios is None else ratios
    if list(ratios) == [1.0]:
        return sigmoid(forward(ps, with_flux(prep(mel)))[-1])
    assert not (FLUX or BACK or WHITEN), "only a perceptron on mel frames (and its short view)"
    views = [context(mel[:, :BANDS])] + ([context(mel[:, BANDS:2 * BANDS])] if SHORT else [])
    out = None
    for r in ratios:
        # Each view retuned by the same ratio and normalised by its own maximum.
        x = np.concatenate([retuned(v, r) for v in views], axis=1)
        a = sigmoid(forward(ps, x)[-1])
        out = a if out is None else out + a
    return (out / np.float32(len(ratios))).astype(np.float32)


def report(ps, thr, sets):
    lines = []
    for name, data in sets:
        for cond in CONDS:
            sel = [(m, t) for (_, _, c, m, t) in data if c == cond]
            if not sel:
                continue
            acts = [activations(ps, m) for m, _ in sel]
            res = score(acts, [t for _, t in sel], thr)
            cells = " | ".join(f"{r[2]:.2f} ({r[0]:.2f}/{r[1]:.2f})" for r in res)
            lines.append(f"| {name} | {cond} | {len(sel)} | {cells} |")
    head = ("| set | input | songs | kick F (P/R) | snare F (P/R) | toms F (P/R) | cymbals F (P/R) |\n"
            "|---|---|---|---|---|---|---|")
    return head + "\n" + "\n".join(lines)


def main():
    global PAST, FUTURE, SHIFT, WARP, STRETCH, FLUX, WHITEN, BACK, SUPER_DB, SHORT, FMASK, EQ_SCALE
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--hidden", default="128,64")
    ap.add_argument("--conds", default="iso,sep")
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument("--no-augment", action="store_true")
    ap.add_argument("--past", type=int, default=PAST, help="context frames before the hop")
    ap.add_argument("--future", type=int, default=FUTURE,
                    help="context frames after the hop (each adds 10 ms of latency)")
    ap.add_argument("--held-out", default=",".join(HELD_OUT),
                    help="families never trained or tuned on (comma-separated)")
    ap.add_argument("--report-md", default=None)
    ap.add_argument("--shift", type=int, default=SHIFT, help="augmentation: +- mel bands")
    ap.add_argument("--warp", type=float, default=WARP,
                    help="augmentation: retune each example by up to this frequency ratio")
    ap.add_argument("--stretch", type=float, default=STRETCH,
                    help="augmentation: stretch each example's context in time by up to this ratio")
    ap.add_argument("--pos-weight", default="4",
                    help="weight of a positive frame, one value or one per class (kick,snare,toms,cymbals)")
    ap.add_argument("--neg-keep", type=float, default=1.0,
                    help="fraction of frames far from any onset used per epoch (1: all)")
    ap.add_argument("--hard-neg", type=float, default=1.0,
                    help="weight of a class's negative frames at another class's onset (1: plain)")
    ap.add_argument("--ghost-weight", type=float, default=1.0,
                    help="weight of a ghost snare's positive (velocity <= 45) in the loss")
    ap.add_argument("--in-drop", type=float, default=0.0, help="input dropout rate (0: none)")
    ap.add_argument("--drop", type=float, default=0.0,
                    help="dropout rate of the hidden layers in training (0: none, the committed recipe)")
    ap.add_argument("--swa", type=float, default=0.0,
                    help="weight averaging: the mean of the weights after every epoch from this "
                         "fraction of the epochs on (0: none, the committed recipe: the best epoch)")
    ap.add_argument("--decay", type=float, default=1e-5, help="L2 weight decay")
    ap.add_argument("--flux", action="store_true",
                    help="input: also the positive first difference of the context's frames")
    ap.add_argument("--families", default=None,
                    help="only these families (comma-separated; default: every one under --data)")
    ap.add_argument("--whiten", type=float, default=0.0,
                    help="input: subtract each band's running mean power over this many seconds "
                         "(adaptive whitening; 0: none)")
    ap.add_argument("--superpose", type=float, default=0.0,
                    help="augmentation: fraction of examples with a window from near another "
                         "onset added in power (0: none, the committed recipe)")
    ap.add_argument("--superpose-db", default="-20,5",
                    help="range of the added window's peak relative to the example's, dB")
    ap.add_argument("--backing", action="store_true",
                    help="input: also the separator's backing (bass + vocals + other) beside "
                         "its drum stem, as a second view (silent for a supplied drum stem)")
    ap.add_argument("--aux", type=float, default=0.0,
                    help="weight of the finer kinds of hit (AUX_KINDS) learnt by extra outputs "
                         "that the written model drops (0: none, the committed recipe)")
    ap.add_argument("--eq-scale", type=float, default=1.0,
                    help="augmentation: the random tilt and EQ's range times this (1: about +-6 dB)")
    ap.add_argument("--freq-mask", type=int, default=0,
                    help="augmentation: silence up to this many adjacent mel bands in half "
                         "the examples (0: none, the committed recipe)")
    ap.add_argument("--short", action="store_true",
                    help="input: also the short view, the same signal's mel frames of a frame "
                         "half as long (1024 points), normalised by their own window's maximum")
    a = ap.parse_args()
    BACK = a.backing
    FMASK = a.freq_mask
    EQ_SCALE = a.eq_scale
    SHORT = a.short
    if SHORT and (BACK or a.flux or a.whiten or a.superpose or a.shift):
        sys.exit("--short goes with none of --backing, --flux, --whiten, --superpose, and "
                 "needs --shift 0 (its augmentation retunes both views instead)")
    SUPER_DB = tuple(float(v) for v in a.superpose_db.split(","))
    if not os.path.exists(dumper_path()):
        sys.exit("build the feature dumper first: cargo build --release -p tactus-engine --example drum_features")
    conds = a.conds.split(",")
    PAST, FUTURE, SHIFT, WARP, STRETCH, FLUX = a.past, a.future, a.shift, a.warp, a.stretch, a.flux
    WHITEN = a.whiten / HOP_S
    HELD_OUT[:] = a.held_out.split(",")
    items = songs(a.data)
    if a.families:
        items = [it for it in items if it[0] in a.families.split(",")]
    pos_weight = [float(v) for v in a.pos_weight.split(",")]
    pos_weight = pos_weight * 4 if len(pos_weight) == 1 else pos_weight
    tr, va, ho = split(items)
    print(f"songs: train {len(tr)}, validation {len(va)}, held out ({','.join(HELD_OUT)}) {len(ho)}", flush=True)
    D_tr, D_va, D_ho = load(tr, a.data, conds), load(va, a.data, CONDS), load(ho, a.data, CONDS)
    if a.report_only:
        ps, thr = read_model(a.out)
    else:
        rng = np.random.default_rng(a.seed)

        def stack(D, cs, hard_neg=1.0, ghost=1.0):
            X, Y, W = [], [], []
            for (_, _, c, mel, truth) in D:
                if c not in cs:
                    continue
                X.append(prep(mel))
                y, w = labels(truth, mel.shape[0], hard_neg, ghost)
                if a.aux > 0:
                    ya, wa = aux_labels(truth, mel.shape[0])
                    y, w = np.concatenate([y, ya], 1), np.concatenate([w, wa * np.float32(a.aux)], 1)
                Y.append(y)
                W.append(w)
            return np.concatenate(X), np.concatenate(Y), np.concatenate(W)

        X, Y, W = stack(D_tr, conds, a.hard_neg, a.ghost_weight)
        Xv, Yv, Wv = stack(D_va, conds)
        if FLUX:  # in chunks: the flux inputs are made per batch, never stored
            s1 = s2 = 0.0
            for s in range(0, len(X), 65536):
                xf = with_flux(X[s:s + 65536]).astype(np.float64)
                s1, s2 = s1 + xf.sum(0), s2 + (xf * xf).sum(0)
            mean = (s1 / len(X)).astype(np.float32)
            std = (np.sqrt(np.maximum(s2 / len(X) - (s1 / len(X)) ** 2, 0)) + 1e-3).astype(np.float32)
        else:
            mean = X.mean(0)
            std = X.std(0) + 1e-3
        print(f"frames: train {len(X)}, validation {len(Xv)}; positives per class {Y.sum(0)}", flush=True)
        n_out = Y.shape[1]
        sizes = [with_flux(X[:1]).shape[1]] + [int(h) for h in a.hidden.split(",")] + [n_out]
        ps = init(sizes, rng)
        pos_weight = pos_weight + [pos_weight[1]] * (n_out - 4)
        ps = train(ps, X, Y, W, Xv, Yv, Wv, a.epochs, rng, pos_weight=pos_weight, mean=mean, std=std,
                   aug=not a.no_augment, neg_keep=a.neg_keep, in_drop=a.in_drop, decay=a.decay, drop=a.drop,
                   sup=a.superpose, swa=a.swa)
        ps[-1] = [ps[-1][0][:4].copy(), ps[-1][1][:4].copy()]  # the four classes' outputs
        # Tune thresholds on validation, over every condition pooled.
        acts = [sigmoid(forward(ps, (with_flux(prep(m)) - mean) / std)[-1]) for (_, _, _, m, _) in D_va]
        thr = tune(acts, [t for (*_, t) in D_va])
        print("thresholds", thr, flush=True)
        write_model(a.out, ps, mean, std, thr)
        ps, thr = read_model(a.out)
    per_fam = [(f"held out: {f}", [d for d in D_ho if d[0] == f]) for f in HELD_OUT]
    md = report(ps, thr, [("validation (training kits)", D_va)] + per_fam)
    print(md)
    if a.report_md:
        with open(a.report_md, "w") as f:
            f.write(md + "\n")


if __name__ == "__main__":
    main()

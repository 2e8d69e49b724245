#!/usr/bin/env python3
"""Trial: song-adaptive re-scoring of the drum transcriber's onsets (issue 10).

A sampled kit plays the same few sounds all song long, so an onset can be judged against the
song's own earlier onsets: a hi-hat that the network half-calls a snare sounds like the
song's other hi-hats, not like its snares. Per class, every candidate onset (the committed
model's activation peak-picked at a lower threshold) gets a song-local opinion: the
activations of its K nearest earlier candidates (any class), weighted by similarity of the
descriptor (the mel frames of the onset's hop and the next ones, minus their maximum). The
re-scored activation is the logit blend `(1 - w) logit(a) + w logit(q)`; the onset is kept
where it reaches the class threshold. Only earlier candidates are used, so it streams with
no added latency beyond the descriptor's frames (inside the model's look-ahead).

Usage (features cached by train.py's dumper):
  python3 models/drums/adapt.py --data /work/data/drums --families timgm,csound,sonicpi \
      --split val [--k 5] [--w 0.5] [--low 0.5]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import train as T  # noqa: E402

EPS = 1e-4


def logit(p):
    p = np.clip(p, EPS, 1 - EPS)
    return np.log(p / (1 - p))


def descriptors(mel, frames):
    n = mel.shape[0]
    last = mel[-1:] if n else np.full((1, T.BANDS), T.LOG_FLOOR, np.float32)
    m = np.concatenate([mel, np.repeat(last, frames, axis=0)])
    idx = np.arange(n)[:, None] + np.arange(frames)[None, :]
    d = m[idx].reshape(n, frames * T.BANDS)
    return np.maximum(d - d.max(axis=1, keepdims=True), T.FLOOR)


def rescore(acts, mel, thr, k, w, low, frames, scale):
    """Onset hops per class after re-scoring."""
    d = descriptors(mel, frames)
    cand = {}
    for c in range(4):
        for i in T.pick(acts[:, c], thr[c] * low):
            cand.setdefault(i, set()).add(c)
    hops = sorted(cand)
    out = [[] for _ in range(4)]
    past_d, past_a = [], []
    for i in hops:
        a = acts[i]
        if past_d:
            D = np.asarray(past_d)
            dist = np.sqrt(((D - d[i]) ** 2).mean(axis=1))
            nn = np.argsort(dist)[:k]
            wt = np.exp(-dist[nn] / scale)
            q = (wt[:, None] * np.asarray(past_a)[nn]).sum(0) / max(wt.sum(), 1e-12)
            score = (1 - w) * logit(a) + w * logit(q) if len(nn) >= k else logit(a)
        else:
            score = logit(a)
        for c in cand[i]:
            if score[c] >= logit(thr[c]):
                out[c].append(i)
        past_d.append(d[i])
        past_a.append(a)
    return out


def evaluate(sel, ps, thr, args):
    res = []
    totals = [[0, 0, 0] for _ in range(4)]
    for mel, truth in sel:
        acts = T.activations(ps, mel)
        if args.w == 0:
            est = [T.pick(acts[:, c], thr[c]) for c in range(4)]
        else:
            est = rescore(acts, mel, thr, args.k, args.w, args.low, args.frames, args.scale)
        for c, name in enumerate(T.CLASSES):
            ref = [h["time_s"] for h in truth.get("onsets", {}).get(name, [])]
            for j, v in enumerate(T.match([i * T.HOP_S for i in est[c]], ref)):
                totals[c][j] += v
    for c in range(4):
        res.append(T.prf(*totals[c]))
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--families", default="timgm,csound,sonicpi")
    ap.add_argument("--split", default="val", choices=["val", "train", "all", "held"])
    ap.add_argument("--conds", default="iso,sep")
    ap.add_argument("--model", default=T.DEFAULT_OUT)
    ap.add_argument("--k", type=int, default=5)
    ap.add_argument("--w", type=float, nargs="+", default=[0.0, 0.5])
    ap.add_argument("--low", type=float, default=0.5)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--scale", type=float, default=1.0)
    args = ap.parse_args()
    ps, thr = T.read_model(args.model)
    fams = set(args.families.split(","))
    items = [it for it in T.songs(args.data) if it[0] in fams]
    tr, va, ho = T.split(items)
    pick = {"val": va, "train": tr, "all": tr + va + ho, "held": ho}[args.split]
    conds = args.conds.split(",")
    data = T.load(pick, args.data, conds)
    ws = args.w
    for cond in conds:
        sel = [(m, t) for (_, _, c, m, t) in data if c == cond]
        for w in ws:
            args.w = w
            r = evaluate(sel, ps, thr, args)
            cells = " | ".join(f"{f:.3f} ({p:.2f}/{rr:.2f})" for p, rr, f in r)
            print(f"| {cond} | {len(sel)} | k {args.k} w {w} low {args.low} fr {args.frames} "
                  f"sc {args.scale} | {cells} |", flush=True)


if __name__ == "__main__":
    main()

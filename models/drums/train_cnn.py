#!/usr/bin/env python3
"""Trial: a small convolutional network in place of the drum transcriber's perceptron.

Same data, split, front end (12 frames x 48 log mel bands, window-max normalised), labels,
augmentation, threshold tuning and peak picking as models/drums/train.py; only the network
differs. Convolutions over time x mel band share their weights across frequency, so a
snare tuned a few bands higher than any training kit still lights the same filters.

Network (input 1 x 12 x 48, time x band; every "valid" in time, "same" in band):
  conv 3x5, 8 channels, ReLU; max-pool 2x2          -> 8 x 5 x 24
  conv 3x3, 16 channels, ReLU; max-pool 1x2         -> 16 x 3 x 12
  dense 576 -> 64, ReLU; dense 64 -> 4, sigmoid
about 180 k multiply-adds per hop.

Usage (training needs torch, CPU is enough):
  python3 models/drums/train_cnn.py --data DIR [train.py's split options] --out FILE
Writes the weights (file version 4, read by crates/tactus-dsp/src/drums.rs) and prints the
report of train.py for the validation and held-out songs.
"""
from __future__ import annotations

import argparse
import os
import struct
import sys

import numpy as np
import torch
from torch import nn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import train as T  # noqa: E402

C1, C2, HID = 8, 16, 64


class Net(nn.Module):
    def __init__(self, win, bands):
        super().__init__()
        self.win, self.bands = win, bands
        self.c1 = nn.Conv2d(1, C1, (3, 5), padding=(0, 2))
        self.c2 = nn.Conv2d(C1, C2, (3, 3), padding=(0, 1))
        t1 = (win - 2) // 2
        t2 = t1 - 2
        self.flat = C2 * t2 * (bands // 4)
        self.d1 = nn.Linear(self.flat, HID)
        self.d2 = nn.Linear(HID, 4)
        nn.init.constant_(self.d2.bias, -3.0)

    def forward(self, x):  # x: (n, win*bands), already standardised
        z = x.view(-1, 1, self.win, self.bands)
        z = torch.max_pool2d(torch.relu(self.c1(z)), (2, 2))
        z = torch.max_pool2d(torch.relu(self.c2(z)), (1, 2))
        z = torch.relu(self.d1(z.flatten(1)))
        return self.d2(z)


def acts_of(net, X, mean, std):
    net.eval()
    out = []
    with torch.no_grad():
        for s in range(0, len(X), 8192):
            x = torch.from_numpy((X[s:s + 8192] - mean) / std)
            out.append(torch.sigmoid(net(x)).numpy())
    return np.concatenate(out) if out else np.zeros((0, 4), np.float32)


def fit(net, X, Y, W, Xv, Yv, Wv, mean, std, epochs, rng, pos_weight, neg_keep, lr=1e-3,
        batch=512, decay=1e-5):
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=decay)
    sched = torch.optim.lr_scheduler.StepLR(opt, step_size=max(1, int(epochs * 0.7) + 1), gamma=0.3)
    near = T.near_onset(Y)
    near_idx, far_idx = np.flatnonzero(near), np.flatnonzero(~near)
    pw = torch.tensor(pos_weight, dtype=torch.float32)
    best = (np.inf, None)
    for ep in range(epochs):
        net.train()
        keep = far_idx[rng.random(len(far_idx)) < neg_keep]
        order = rng.permutation(np.concatenate([near_idx, keep]))
        tot = 0.0
        for s in range(0, len(order), batch):
            idx = order[s:s + batch]
            x = T.augment(X[idx], rng)
            w = W[idx] * np.where(near[idx], 1.0, 1.0 / neg_keep).astype(np.float32)[:, None]
            xt = torch.from_numpy((x - mean) / std)
            yt, wt = torch.from_numpy(Y[idx]), torch.from_numpy(w)
            z = net(xt)
            ww = wt * (1 + (pw - 1) * yt)
            loss = (nn.functional.binary_cross_entropy_with_logits(z, yt, reduction="none") * ww).sum() / len(idx)
            opt.zero_grad()
            loss.backward()
            opt.step()
            tot += float(loss.detach()) * len(idx)
        sched.step()
        pv = acts_of(net, Xv, mean, std)
        ww = Wv * (1 + (np.asarray(pos_weight, np.float32) - 1) * Yv)
        vl = float(-(ww * (Yv * np.log(pv + 1e-7) + (1 - Yv) * np.log(1 - pv + 1e-7))).sum() / len(Xv))
        print(f"epoch {ep + 1}: train {tot / len(order):.4f} val {vl:.4f}", flush=True)
        if vl < best[0]:
            best = (vl, {k: v.clone() for k, v in net.state_dict().items()})
    net.load_state_dict(best[1])
    return net


def write_model(path, net, mean, std, thr):
    """File version 4 (crates/tactus-dsp/src/drums.rs): "TACTUSDR", u32 version = 4, bands,
    past, future, classes = 4, dense layers; f32 floor; u32 conv layers; f32 mean and std of
    the standardisation (window_len values each); per conv layer u32 out, in, kt, kb, pool_t,
    pool_b and f32 w[out][in][kt][kb], b[out]; per dense layer u32 n_in, n_out, f32 w, b;
    f32 thresholds[4]."""
    sd = {k: v.detach().numpy().astype("<f4") for k, v in net.state_dict().items()}
    with open(path + ".tmp", "wb") as f:
        f.write(b"TACTUSDR")
        f.write(struct.pack("<6I", 4, T.BANDS, T.PAST, T.FUTURE, 4, 2))
        f.write(struct.pack("<f", T.FLOOR))
        f.write(struct.pack("<I", 2))
        f.write(np.asarray(mean, "<f4").tobytes())
        f.write(np.asarray(std, "<f4").tobytes())
        for name, pool in (("c1", (2, 2)), ("c2", (1, 2))):
            w = sd[f"{name}.weight"]
            f.write(struct.pack("<6I", *w.shape, *pool))
            f.write(np.ascontiguousarray(w).tobytes())
            f.write(sd[f"{name}.bias"].tobytes())
        for name in ("d1", "d2"):
            w = sd[f"{name}.weight"]
            f.write(struct.pack("<2I", w.shape[1], w.shape[0]))
            f.write(np.ascontiguousarray(w).tobytes())
            f.write(sd[f"{name}.bias"].tobytes())
        f.write(np.asarray(thr, "<f4").tobytes())
    os.replace(path + ".tmp", path)


def write_ensemble(path, member_files, thr):
    """The ensemble file of crates/tactus-dsp/src/drums.rs: "TACTUSDE", u32 version = 1,
    members, per member u32 byte length + the member's whole file, f32 thresholds[4]."""
    with open(path + ".tmp", "wb") as f:
        f.write(b"TACTUSDE")
        f.write(struct.pack("<2I", 1, len(member_files)))
        for m in member_files:
            with open(m, "rb") as g:
                blob = g.read()
            f.write(struct.pack("<I", len(blob)))
            f.write(blob)
        f.write(np.asarray(thr, "<f4").tobytes())
    os.replace(path + ".tmp", path)


def combine(a, D_va, D_ho):
    """--combine MLP.bin CNN.bin: average the two networks' activations, tune thresholds on
    the validation songs for the average, write the ensemble file, report."""
    mlp_file, cnn_file = a.combine
    ps, _ = T.read_model(mlp_file)
    ck = torch.load(cnn_file + ".pt", weights_only=False)
    net = Net(T.PAST + 1 + T.FUTURE, T.BANDS)
    net.load_state_dict(ck["net"])

    def avg(mel):
        x = T.prep(mel)
        return 0.5 * (T.sigmoid(T.forward(ps, x)[-1]) + acts_of(net, x, ck["mean"], ck["std"]))

    acts_va = [avg(m) for (*_, m, _) in D_va]
    thr = T.tune(acts_va, [t for (*_, t) in D_va])
    print("thresholds", thr, flush=True)
    write_ensemble(a.out, [mlp_file, cnn_file], thr)
    return avg, thr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--combine", nargs=2, metavar=("MLP", "CNN"), default=None,
                    help="write the ensemble of a train.py model and a model of this script "
                         "(its .pt beside it) to --out, thresholds tuned on validation")
    ap.add_argument("--data", required=True)
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--held-out", default="fluid,musescore")
    ap.add_argument("--families", default=None)
    ap.add_argument("--neg-keep", type=float, default=0.5)
    ap.add_argument("--warp", type=float, default=1.5)
    ap.add_argument("--stretch", type=float, default=1.5)
    ap.add_argument("--shift", type=int, default=0)
    ap.add_argument("--future", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--dump-acts", default=None, help="write held-out/validation activations (npz)")
    ap.add_argument("--score-held-out", action="store_true",
                    help="also score the held-out families (default: validation only, so a "
                         "trial can be trained before its adoption rule looks at them)")
    a = ap.parse_args()
    torch.manual_seed(a.seed)
    torch.set_num_threads(a.threads)
    T.FUTURE, T.WARP, T.STRETCH, T.SHIFT = a.future, a.warp, a.stretch, a.shift
    T.HELD_OUT[:] = a.held_out.split(",")
    items = T.songs(a.data)
    if a.families:
        items = [it for it in items if it[0] in a.families.split(",")]
    tr, va, ho = T.split(items)
    print(f"songs: train {len(tr)}, validation {len(va)}, held out {len(ho)}", flush=True)
    D_tr, D_va, D_ho = T.load(tr, a.data, ["iso", "sep"]), T.load(va, a.data, T.CONDS), T.load(ho, a.data, T.CONDS)

    def stack(D, cs):
        X, Y, W = [], [], []
        for (_, _, c, mel, truth) in D:
            if c in cs:
                X.append(T.prep(mel))
                y, w = T.labels(truth, mel.shape[0])
                Y.append(y)
                W.append(w)
        return np.concatenate(X), np.concatenate(Y), np.concatenate(W)

    if a.combine:
        avg, thr = combine(a, D_va, D_ho)
        report(a, avg, thr, D_va, D_ho)
        return
    rng = np.random.default_rng(a.seed)
    X, Y, W = stack(D_tr, ["iso", "sep"])
    Xv, Yv, Wv = stack(D_va, ["iso", "sep"])
    mean, std = X.mean(0), X.std(0) + 1e-3
    print(f"frames: train {len(X)}, validation {len(Xv)}", flush=True)
    net = Net(T.PAST + 1 + T.FUTURE, T.BANDS)
    net = fit(net, X, Y, W, Xv, Yv, Wv, mean, std, a.epochs, rng, [4.0] * 4, a.neg_keep)
    acts_va = [acts_of(net, T.prep(m), mean, std) for (*_, m, _) in D_va]
    thr = T.tune(acts_va, [t for (*_, t) in D_va])
    print("thresholds", thr, flush=True)
    write_model(a.out, net, mean, std, thr)
    torch.save({"net": net.state_dict(), "mean": mean, "std": std, "thr": thr}, a.out + ".pt")
    report(a, lambda m: acts_of(net, T.prep(m), mean, std), thr, D_va, D_ho)


def report(a, act_fn, thr, D_va, D_ho):
    lines = []
    sets = [("validation", D_va)]
    if a.score_held_out:
        sets += [(f"held out: {f}", [d for d in D_ho if d[0] == f]) for f in T.HELD_OUT]
    dump = {}
    for name, data in sets:
        for cond in T.CONDS:
            sel = [(f"{fam}/{s}", m, t) for (fam, s, c, m, t) in data if c == cond]
            if not sel:
                continue
            acts = [act_fn(m) for _, m, _ in sel]
            for (s, _, _), ac in zip(sel, acts):
                dump[f"{cond}|{s}"] = ac
            res = T.score(acts, [t for *_, t in sel], thr)
            cells = " | ".join(f"{r[2]:.3f} ({r[0]:.2f}/{r[1]:.2f})" for r in res)
            lines.append(f"| {name} | {cond} | {len(sel)} | {cells} |")
    print("| set | input | songs | kick | snare | toms | cymbals |\n|---|---|---|---|---|---|---|")
    print("\n".join(lines))
    if a.dump_acts:
        np.savez_compressed(a.dump_acts, **dump)


if __name__ == "__main__":
    main()

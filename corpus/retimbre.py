#!/usr/bin/env python3
"""Corpus songs with the bass or the lead played by a synthesiser: an out-of-distribution set
with the songs' own truth.

Every pitch model of Tactus was trained on sampled instruments (soundfonts) and a sung
voice. A sub-bass of electronic music is an oscillator: a sustained sine with a little
second harmonic (the "808" bass), and synth leads are saws and squares. This script replaces
one part of a song by such an oscillator playing the truth's own pitch track, and writes a
new song folder beside it: the same truth, the other stems untouched, the mix their sum.

The new part, at the file's rate, in float64:
1. pitch: the truth's `f0_hz[PART]` (one value per 10 ms hop, 0 for a rest), held over each
   hop, through a phase accumulator (no click at a change of note);
2. level: the original stem's RMS per hop (both channels' mean), so that the part keeps the
   song's dynamics and its balance in the mix; silent where the truth rests, with 5 ms
   linear ramps at every start and end of a voiced run;
3. timbre (`--timbre`): `808` sin(p) + 0.15 sin(2p), `sine`, `saw` (the naive ramp, which
   aliases above Nyquist as cheap synths do), `square` (its sign); for training data,
   `sine-h` (a sine with a second and third harmonic of random weights, 0-0.3 and 0-0.1,
   drawn per song from `--seed`) and `saw-lp` (the saw through a one-pole low-pass at a
   random 200-1500 Hz); each scaled to unit RMS before the level is applied;
4. centred: the same signal in both channels.

Written as 16-bit PCM WAV (the part's stem and `mix.wav`, each through a temporary file and
a rename); the other stems and `truth.json` are copied. Deterministic: the training timbres' draws are seeded per song.

    corpus/.venv/bin/python corpus/retimbre.py --part bass --timbre 808 --out OOD SONG_DIR...

Songs keep their folder name; a song under `DIR/FAMILY/SONG` goes to `OUT/FAMILY/SONG`.
"""
import argparse
import json
import os
import shutil
import wave

import numpy as np

STEMS = ("drums", "bass", "other", "vocals")
RAMP_S = 0.005


def read_wav(path):
    with wave.open(path, "rb") as w:
        if w.getsampwidth() != 2:
            raise SystemExit(f"{path}: expected 16-bit PCM")
        ch, rate = w.getnchannels(), w.getframerate()
        x = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(np.float64) / 32768
    return x.reshape(-1, ch), rate


def write_wav(path, x, rate):
    pcm = np.clip(np.round(x * 32767), -32768, 32767).astype("<i2")
    tmp = path + ".tmp"
    with wave.open(tmp, "wb") as w:
        w.setnchannels(x.shape[1])
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(pcm.reshape(-1).tobytes())
    os.replace(tmp, path)


def unit(timbre, phase, rng=None, rate=44100):
    """The waveform at `phase` (cycles), scaled to unit RMS (`rng` draws the training
    timbres' parameters)."""
    p = 2 * np.pi * phase
    if timbre == "sine-h":
        h2, h3 = rng.uniform(0.0, 0.3), rng.uniform(0.0, 0.1)
        return (np.sin(p) + h2 * np.sin(2 * p) + h3 * np.sin(3 * p)) / np.sqrt(
            0.5 * (1 + h2 ** 2 + h3 ** 2))
    if timbre == "saw-lp":
        a = np.exp(-2 * np.pi * rng.uniform(200.0, 1500.0) / rate)
        x = 2 * (phase % 1.0) - 1
        y = np.empty_like(x)
        acc = 0.0
        for i, v in enumerate(x.tolist()):
            acc = (1 - a) * v + a * acc
            y[i] = acc
        return y / max(np.sqrt(np.mean(y ** 2)), 1e-12)
    if timbre == "808":
        return (np.sin(p) + 0.15 * np.sin(2 * p)) / np.sqrt(0.5 * (1 + 0.15 ** 2))
    if timbre == "sine":
        return np.sin(p) * np.sqrt(2)
    if timbre == "saw":
        return (2 * (phase % 1.0) - 1) * np.sqrt(3)
    if timbre == "square":
        return np.where(phase % 1.0 < 0.5, 1.0, -1.0)
    raise SystemExit(f"unknown timbre {timbre}")


def resynth(f0_hops, hop_s, level_hops, n, rate, timbre, rng=None):
    """The part: `f0_hops` and `level_hops` (RMS) per hop of `hop_s`, `n` samples."""
    idx = np.minimum((np.arange(n) / rate / hop_s).astype(int), len(f0_hops) - 1)
    f0 = np.asarray(f0_hops, dtype=np.float64)[idx]
    voiced = f0 > 0
    phase = np.cumsum(np.where(voiced, f0, 0.0) / rate)
    # Gate: 1 on voiced samples, with linear ramps of RAMP_S inside each run's edges.
    ramp = max(1, int(RAMP_S * rate))
    g = np.zeros(n)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], voiced.astype(np.int8), [0]])))
    for start, end in zip(edges[0::2], edges[1::2]):
        k = np.arange(end - start)
        g[start:end] = np.minimum(1.0, np.minimum(k + 1, end - start - k) / ramp)
    level = np.asarray(level_hops, dtype=np.float64)[idx]
    return unit(timbre, phase, rng, rate) * level * g


def rms_per_hop(x, rate, hop_s, hops):
    mono = x.mean(axis=1)
    h = int(round(hop_s * rate))
    out = np.zeros(hops)
    for i in range(hops):
        seg = mono[i * h:(i + 1) * h]
        out[i] = np.sqrt(np.mean(seg ** 2)) if len(seg) else 0.0
    return out


def retimbre(song, dst, part, timbre, seed):
    truth = json.load(open(os.path.join(song, "truth.json")))
    stems = {s: read_wav(os.path.join(song, f"{s}.wav")) for s in STEMS}
    rate = stems[part][1]
    x = stems[part][0]
    hop_s = truth["hop_s"]
    f0 = truth["f0_hz"][part]
    level = rms_per_hop(x, rate, hop_s, len(f0))
    # The level of a voiced hop, not of the note's silent tail: the original stem's RMS is
    # the instrument's, so a plucked note decays and a held one holds, as played.
    y = resynth(f0, hop_s, level, x.shape[0], rate, timbre, np.random.default_rng(seed))
    new = np.stack([y, y], axis=1)
    mix = sum(stems[s][0] for s in STEMS if s != part) + new
    os.makedirs(dst, exist_ok=True)
    for name in os.listdir(song):
        if name not in (f"{part}.wav", "mix.wav") and (
            name.endswith(".wav") or name == "truth.json"
        ):
            shutil.copyfile(os.path.join(song, name), os.path.join(dst, name))
    write_wav(os.path.join(dst, f"{part}.wav"), new, rate)
    write_wav(os.path.join(dst, "mix.wav"), mix, rate)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--part", choices=("bass", "vocals"), default="bass")
    ap.add_argument("--timbre", choices=("808", "sine", "saw", "square", "sine-h", "saw-lp"),
                    default="808")
    ap.add_argument("--seed", type=int, default=0, help="first song's seed (training timbres)")
    ap.add_argument("songs", nargs="+")
    args = ap.parse_args()
    for i, song in enumerate(args.songs):
        song = os.path.normpath(song)
        family = os.path.basename(os.path.dirname(song))
        dst = os.path.join(args.out, family, os.path.basename(song))
        if os.path.abspath(dst) == os.path.abspath(song):
            raise SystemExit(f"{song}: --out would overwrite the song")
        retimbre(song, dst, args.part, args.timbre, args.seed + i)
        print(dst)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A production chain over corpus songs: an out-of-distribution set with the songs' own truth.

Every model and rule of Tactus was trained and tuned on dry sums of rendered stems. Real
records are mixed: a room, a bus compressor, some drive, a limiter on the master. This
script puts a song's mix through such a chain and writes a new song folder beside it, with
the same truth (every effect is causal and adds no delay to the direct sound, so onsets and
pitches stay where the truth says) and the same isolated stems (the chain is a mix effect).

Chain, in order, all in float64 at the file's rate, deterministic (seeded):
1. room reverb: the mix convolved with exponentially decaying noise (RT60 `--rt60` s, 12 ms
   pre-delay, darkened by a one-pole low-pass at 5 kHz), added at `--wet` of the dry level;
2. bus compressor: feed-forward on a 30 ms RMS detector, threshold -24 dBFS, ratio 4:1,
   make-up gain to the input's RMS;
3. overdrive: tanh(d·x)/tanh(d) with d = `--drive`, a quarter of the signal replaced;
4. master limiter: gain min(1, ceiling/|x|) with a 5 ms look-around minimum, ceiling -1 dBFS,
   then normalised so the peak is at the ceiling.

Written as 16-bit PCM WAV (`mix.wav`); the stems and `truth.json` are copied.

    corpus/.venv/bin/python corpus/produce.py --out /work/data/ood/prod SONG_DIR...

Songs keep their folder name; a song under `DIR/FAMILY/SONG` goes to `OUT/FAMILY/SONG`.
"""
import argparse
import os
import shutil
import wave

import numpy as np
from scipy.ndimage import minimum_filter1d
from scipy.signal import fftconvolve, lfilter


def read_wav(path):
    with wave.open(path, "rb") as w:
        if w.getsampwidth() != 2:
            raise SystemExit(f"{path}: expected 16-bit PCM")
        ch, rate = w.getnchannels(), w.getframerate()
        x = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(np.float64) / 32768
    return x.reshape(-1, ch).mean(axis=1), rate


def write_wav(path, x, rate):
    pcm = np.clip(np.round(x * 32767), -32768, 32767).astype("<i2")
    tmp = path + ".tmp"
    with wave.open(tmp, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(pcm.tobytes())
    os.replace(tmp, path)


def one_pole_lowpass(x, rate, hz):
    a = np.exp(-2 * np.pi * hz / rate)
    return lfilter([1 - a], [1, -a], x)


def reverb(x, rate, rt60, wet, rng):
    n = int(rate * rt60 * 1.2)
    t = np.arange(n) / rate
    ir = rng.standard_normal(n) * 10 ** (-3 * t / rt60)
    ir = one_pole_lowpass(ir, rate, 5000.0)
    ir = np.concatenate([np.zeros(int(0.012 * rate)), ir])
    ir *= wet / np.sqrt(np.sum(ir ** 2))
    return x + fftconvolve(x, ir)[: len(x)]


def compress(x, rate, threshold_db=-24.0, ratio=4.0):
    a = np.exp(-1 / (0.030 * rate))
    power = lfilter([1 - a], [1, -a], x ** 2)
    level_db = 10 * np.log10(np.maximum(power, 1e-12))
    over = np.maximum(level_db - threshold_db, 0.0)
    y = x * 10 ** (-over * (1 - 1 / ratio) / 20)
    rms_in, rms_out = np.sqrt(np.mean(x ** 2)), np.sqrt(np.mean(y ** 2))
    return y * (rms_in / rms_out if rms_out > 0 else 1.0)


def overdrive(x, drive):
    return 0.75 * x + 0.25 * np.tanh(drive * x) / np.tanh(drive)


def limit(x, rate, ceiling_db=-1.0):
    c = 10 ** (ceiling_db / 20)
    need = np.minimum(1.0, c / np.maximum(np.abs(x), 1e-12))
    g = minimum_filter1d(need, size=int(0.005 * rate) | 1)
    y = x * g
    return y * (c / max(np.max(np.abs(y)), 1e-12))


def produce(song, dst, args, seed):
    x, rate = read_wav(os.path.join(song, "mix.wav"))
    rng = np.random.default_rng(seed)
    y = reverb(x, rate, args.rt60, args.wet, rng)
    y = compress(y, rate)
    y = overdrive(y / max(np.max(np.abs(y)), 1e-12), args.drive)
    y = limit(y, rate)
    os.makedirs(dst, exist_ok=True)
    for name in os.listdir(song):
        if name != "mix.wav" and (name.endswith(".wav") or name == "truth.json"):
            shutil.copyfile(os.path.join(song, name), os.path.join(dst, name))
    write_wav(os.path.join(dst, "mix.wav"), y, rate)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--rt60", type=float, default=0.6)
    ap.add_argument("--wet", type=float, default=0.35)
    ap.add_argument("--drive", type=float, default=3.0)
    ap.add_argument("songs", nargs="+")
    args = ap.parse_args()
    for i, song in enumerate(args.songs):
        song = os.path.normpath(song)
        family = os.path.basename(os.path.dirname(song))
        dst = os.path.join(args.out, family, os.path.basename(song))
        produce(song, dst, args, seed=1000 + i)
        print(dst)


if __name__ == "__main__":
    main()

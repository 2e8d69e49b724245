#!/usr/bin/env python3
"""Peer timings for Tactus's pitch (YIN / pYIN) and onset (spectral flux) kernels.

Setup (once):
    python3 -m venv benches/peers/.venv
    benches/peers/.venv/bin/pip install -r benches/peers/requirements.txt
Run:
    benches/peers/.venv/bin/python benches/peers/peers.py

Generates a deterministic 180 s, 44.1 kHz mono signal (harmonic melody with vibrato plus
decaying noise-burst drum hits), writes it as 32-bit float WAV to benches/peers/signal.wav
(so a Rust harness can read the very same samples), times every peer kernel on it
(best of 3 `time.perf_counter` runs; a kernel whose first run takes > 30 s is timed once)
and prints a JSON object of timings in seconds. aubio is optional (it has no wheels and
builds from source); it is skipped if it does not import.

Threads are pinned to 1 (OMP/MKL/OpenBLAS/numba) before numpy is imported, since the
Tactus kernels are single-threaded; pass --threads N to change that.
"""
import argparse
import json
import os
import platform
import sys
import time

ap = argparse.ArgumentParser()
ap.add_argument("--seconds", type=float, default=180.0)
ap.add_argument("--repeats", type=int, default=3)
ap.add_argument("--threads", type=int, default=1)
ap.add_argument("--skip-pyin", action="store_true")
args = ap.parse_args()
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[var] = str(args.threads)

import numpy as np  # noqa: E402
import soundfile as sf  # noqa: E402
import librosa  # noqa: E402

try:
    import aubio  # noqa: E402
except Exception as e:  # pragma: no cover - optional peer
    aubio = None
    AUBIO_ERR = repr(e)
else:
    AUBIO_ERR = None

SR = 44100
FRAME = 2048
HOP = 512
FMIN, FMAX = 50.0, 2000.0
HERE = os.path.dirname(os.path.abspath(__file__))


def make_signal(seconds: float) -> np.ndarray:
    """Harmonic melody (notes every 0.25 s, 5.5 Hz vibrato, 4 harmonics) + drum hits."""
    rng = np.random.default_rng(20261123)
    n = int(seconds * SR)
    t = np.arange(n) / SR
    # Melody: a fixed pseudo-random walk over two octaves from A2, one note per 0.25 s.
    n_notes = int(np.ceil(seconds * 4))
    steps = rng.integers(-3, 4, size=n_notes)
    notes = np.clip(np.cumsum(steps), 0, 24)
    semis = notes[(t * 4).astype(np.int64)]
    f0 = 110.0 * 2.0 ** (semis / 12.0) * (1.0 + 0.01 * np.sin(2 * np.pi * 5.5 * t))
    phase = 2 * np.pi * np.cumsum(f0) / SR
    mel = sum(a * np.sin(k * phase) for k, a in ((1, 0.5), (2, 0.25), (3, 0.15), (4, 0.08)))
    # Drum hits: every 0.5 s, with a little fixed jitter; decaying noise burst + 60 Hz thump.
    drums = np.zeros(n)
    hit_len = int(0.2 * SR)
    th = np.arange(hit_len) / SR
    env = np.exp(-th / 0.03)
    for k, start in enumerate(range(0, n - hit_len, SR // 2)):
        start += int(rng.integers(0, 200))
        amp = 0.6 if k % 2 == 0 else 0.35
        burst = env * (0.6 * rng.standard_normal(hit_len) + 0.8 * np.sin(2 * np.pi * 60 * th))
        drums[start:start + hit_len] += amp * burst
    x = 0.5 * mel + drums + 0.005 * rng.standard_normal(n)
    x /= np.max(np.abs(x)) * 1.01
    return x.astype(np.float32)


def timeit(fn, repeats):
    """Best of `repeats` perf_counter runs; once only if the first run exceeds 30 s."""
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
        if times[0] > 30.0:
            break
    return {"best_s": min(times), "runs_s": times}, out


def aubio_pitch(method, x):
    p = aubio.pitch(method, FRAME, HOP, SR)
    p.set_unit("Hz")
    out = np.empty(len(x) // HOP, dtype=np.float32)
    for i in range(len(out)):
        out[i] = p(x[i * HOP:(i + 1) * HOP])[0]
    return out


def aubio_onsets(method, x):
    o = aubio.onset(method, FRAME, HOP, SR)
    hits = []
    for i in range(len(x) // HOP):
        if o(x[i * HOP:(i + 1) * HOP])[0]:
            hits.append(o.get_last())
    return hits


def main():
    load_before = os.getloadavg()
    x = make_signal(args.seconds)
    wav = os.path.join(HERE, "signal.wav")
    sf.write(wav, x, SR, subtype="FLOAT")
    assert np.array_equal(sf.read(wav, dtype="float32")[0], x)

    kernels = {
        "librosa.yin": lambda: librosa.yin(x, fmin=FMIN, fmax=FMAX, sr=SR,
                                           frame_length=FRAME, hop_length=HOP),
        "librosa.onset.onset_detect": lambda: librosa.onset.onset_detect(
            y=x, sr=SR, hop_length=HOP),
    }
    if not args.skip_pyin:
        kernels["librosa.pyin"] = lambda: librosa.pyin(x, fmin=FMIN, fmax=FMAX, sr=SR,
                                                       frame_length=FRAME, hop_length=HOP)
    if aubio is not None:
        kernels["aubio.pitch(yin)"] = lambda: aubio_pitch("yin", x)
        kernels["aubio.pitch(yinfast)"] = lambda: aubio_pitch("yinfast", x)
        kernels["aubio.pitch(yinfft)"] = lambda: aubio_pitch("yinfft", x)
        kernels["aubio.onset(specflux)"] = lambda: aubio_onsets("specflux", x)

    # Warm-up on 2 s so numba JIT compilation / caches are not in the timings.
    xs = x[: 2 * SR]
    librosa.yin(xs, fmin=FMIN, fmax=FMAX, sr=SR, frame_length=FRAME, hop_length=HOP)
    librosa.onset.onset_detect(y=xs, sr=SR, hop_length=HOP)
    if not args.skip_pyin:
        librosa.pyin(xs, fmin=FMIN, fmax=FMAX, sr=SR, frame_length=FRAME, hop_length=HOP)

    results = {}
    for name, fn in kernels.items():
        r, out = timeit(fn, args.repeats)
        if name == "librosa.onset.onset_detect" or name.startswith("aubio.onset"):
            r["n_onsets"] = len(out)
        print(f"{name}: {r['best_s']:.3f} s", file=sys.stderr, flush=True)
        results[name] = r

    report = {
        "signal": {"seconds": args.seconds, "sr": SR, "samples": len(x), "wav": wav},
        "config": {"frame": FRAME, "hop": HOP, "fmin": FMIN, "fmax": FMAX,
                   "threads": args.threads, "repeats": args.repeats},
        "versions": {"python": platform.python_version(), "numpy": np.__version__,
                     "librosa": librosa.__version__,
                     "aubio": getattr(aubio, "version", None) if aubio else None},
        "aubio_error": AUBIO_ERR,
        "loadavg_before_after": [load_before, os.getloadavg()],
        "timings": results,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

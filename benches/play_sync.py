#!/usr/bin/env python3
"""How closely `tactus play` holds its frames to the audio it plays, measured from outside
(issue 15: "within ±10 ms of the audio clock over a 3.5-minute song").

Real stand-ins only:

* a private PulseAudio server (its own XDG_RUNTIME_DIR) with a null sink `vsink` at 48 kHz:
  `tactus play` (built with `--features audio`) plays the song into it through cpal/ALSA;
* `parec` records the sink's monitor in 5 ms fragments; each fragment is stamped when it
  arrives (CLOCK_MONOTONIC), so a monitor sample's wall time is known to within a fragment
  (the lower envelope of `arrival - samples/rate` over a sliding window is taken as the
  time the sink rendered it);
* a socat pty pair: `tactus play --glove serial:ttyA`; this script reads the wire protocol
  from the other end and stamps each packet when its last byte arrived (as
  `benches/live_latency.py` does). A packet carries its frame's time since the start
  of the song (ms, u16, unwrapped here).

The song's position in the monitor recording is found by cross-correlating 1 s excerpts
of the decoded song (ffmpeg, 48 kHz mono) with the recording every 5 s, so a dropped or
repeated stretch of audio shows up as a change of lag. For each frame, "lead" = the wall
time its song position was rendered by the sink minus the packet's arrival: `play` sends
frames early by the pin rise (50 ms) plus the link's latency, so the lead should be
constant at that value; its spread is how closely the frames follow the audio clock.

    python3 benches/play_sync.py --tactus target/release/tactus SONG [--pattern P.json]
        [--json OUT.json] [-- extra tactus play arguments]

Without `--pattern` it measures `play SONG` (frames rendered as the song plays); with it,
`play PATTERN.json` (the pattern's own song, verified by SHA-256). Needs numpy, ffmpeg,
pulseaudio, pulseaudio-utils and socat; exit code 3 when one is missing.
"""

import argparse
import faulthandler
import signal
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from live_latency import Reader, pct, pty_pair, start_pulse, tear_down  # noqa: E402  (same directory)

RATE = 48_000
WINDOW_S = 0.5  # excerpt correlated with the recording
STEP_S = 0.5  # one lag estimate per STEP_S of song (a dropout moves the lag)
ENVELOPE_S = 2.0  # half-width of the window for the arrival lower envelope


class Recorder(threading.Thread):
    """Reads `parec`'s raw s16le mono output, stamping every read."""

    def __init__(self, proc):
        super().__init__(daemon=True)
        self.proc = proc
        self.data = bytearray()
        self.stamps = []  # (samples so far, arrival)

    def run(self):
        fd = self.proc.stdout.fileno()
        while True:
            try:
                b = os.read(fd, 4096)
            except OSError:
                break
            now = time.monotonic()
            if not b:
                break
            self.data += b
            self.stamps.append((len(self.data) // 2, now))


def need(prog):
    if shutil.which(prog) is None:
        print(f"play_sync: {prog} is not installed "
              "(apt-get install pulseaudio pulseaudio-utils socat ffmpeg)", file=sys.stderr)
        sys.exit(3)


def decode(song, np):
    raw = subprocess.run(["ffmpeg", "-v", "error", "-i", song, "-ac", "1", "-ar", str(RATE),
                          "-f", "f32le", "-"], check=True, stdout=subprocess.PIPE).stdout
    return np.frombuffer(raw, dtype=np.float32).astype(np.float64)


def lags(song, rec, np):
    """[(song sample, monitor sample - song sample or None, peak quality)] every STEP_S.

    The lag can only grow (a dropout delays the rest of the song; nothing plays early) and
    music repeats itself (bars, loops), so each excerpt is looked for from the last lag
    (less 20 ms) to 3 s after it, and the earliest peak within 3 % of the best one is
    taken (r > 0.8); when nothing there correlates, the excerpt is left out."""
    w = int(WINDOW_S * RATE)
    step = int(STEP_S * RATE)
    back = int(0.02 * RATE)
    out = []
    prev = None
    c2 = np.concatenate(([0.0], np.cumsum(rec * rec)))
    for p in range(0, len(song) - w, step):
        x = song[p:p + w]
        if np.sqrt(np.mean(x * x)) < 1e-3:
            continue  # silence: nothing to align
        first = 0 if prev is None else max(0, p + prev - back)
        spans = [(first, len(rec) if prev is None else min(len(rec), p + prev + w + 3 * RATE))]
        for lo, hi in spans:
            y = rec[lo:hi]
            if len(y) < w:
                continue
            n = 1 << int(math.ceil(math.log2(len(y) + w)))
            c = np.fft.irfft(np.fft.rfft(y, n) * np.conj(np.fft.rfft(x, n)), n)[:len(y) - w + 1]
            # Normalised by the recording's energy under the excerpt.
            e = np.sqrt(np.maximum(c2[lo + w:hi + 1] - c2[lo:hi - w + 1], 1e-12))
            r = c / (e * np.sqrt(np.sum(x * x)))
            best = float(r.max())
            if best > 0.8:
                k = int(np.argmax(r >= 0.97 * best))
                prev = lo + k - p
                out.append((p, prev, float(r[k])))
                break
        else:
            out.append((p, None, 0.0))
    return out


def run(args, extra, np):
    for p in ("pulseaudio", "pactl", "parec", "socat", "ffmpeg"):
        need(p)
    d = tempfile.mkdtemp(prefix="tactus-sync-")
    env = dict(os.environ, XDG_RUNTIME_DIR=os.path.join(d, "rt"))
    procs = []
    try:
        # Real-time, as a desktop's PulseAudio runs (rtkit): on a loaded machine a
        # normal-priority server drops out for hundreds of ms, and those gaps are the
        # sound server's, not the player's.
        env = start_pulse(d, RATE, ("--realtime=yes", "--high-priority=yes"))
        subprocess.run(["pactl", "set-default-sink", "vsink"], env=env, check=True)
        socat, a, b = pty_pair(d)
        procs.append(socat)
        reader = Reader(b)
        reader.start()
        parec = subprocess.Popen(["parec", "-d", "vsink.monitor", "--raw", "--format=s16le",
                                  f"--rate={RATE}", "--channels=1", "--latency-msec=5"],
                                 stdout=subprocess.PIPE, env=env)
        procs.append(parec)
        rec = Recorder(parec)
        rec.start()
        time.sleep(1.0)
        target = args.pattern if args.pattern else args.song
        play = subprocess.run([args.tactus, "play", target, "--glove", f"serial:{a}", *extra],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        err = play.stderr.decode(errors="replace")
        if play.returncode != 0:
            # Still analysed: where the sound and the frames stopped is the finding.
            print(f"play_sync: tactus play failed ({play.returncode}): {err}", file=sys.stderr)
        if "tactus: audio on " not in err:
            raise RuntimeError("tactus played no audio (build it with --features audio): " + err)
        time.sleep(0.5)
        reader.stop = True
        parec.terminate()
        rec.join(timeout=5)
    finally:
        tear_down(procs, env, d)
    y = np.frombuffer(bytes(rec.data[:len(rec.data) // 2 * 2]), dtype="<i2") / 32768.0
    if os.environ.get("PLAY_SYNC_DEBUG"):
        np.save("/tmp/play_sync_rec.npy", y)
        np.save("/tmp/play_sync_stamps.npy", np.array(rec.stamps))
        with open("/tmp/play_sync_packets.json", "w") as f:
            json.dump({"packets": [(t, k, q, m, list(c)) for t, k, q, m, c in reader.packets],
                       "bad": reader.bad, "err": err, "rc": play.returncode}, f)
    return analyse(args, np, reader.packets, reader.bad, y, rec.stamps, err, play.returncode)


def analyse(args, np, packets, bad, y, stamps, err, play_rc):
    song = decode(args.song, np)
    # Wall time of monitor sample m: m / RATE + the lower envelope of (arrival - count/RATE)
    # around m (a fragment arrives at the earliest when its last sample was rendered).
    n = np.array([s for s, _ in stamps], dtype=np.float64)
    off = np.array([t - s / RATE for s, t in stamps])
    half = ENVELOPE_S * RATE

    def wall(m):
        lo, hi = np.searchsorted(n, m - half), np.searchsorted(n, m + half)
        return m / RATE + off[lo:max(hi, lo + 1)].min()

    lag = lags(song, y, np)
    good = [(p, l) for p, l, q in lag if l is not None]
    if not good:
        raise RuntimeError("the song was not found in the monitor recording")
    changes = sum(1 for i in range(1, len(good)) if good[i][1] != good[i - 1][1])
    gp = np.array([p for p, _ in good])

    def lag_at(p):
        return good[max(0, min(len(good) - 1, int(np.searchsorted(gp, p, "right")) - 1))][1]

    # First arrival of each frame time (ms since the song's start, unwrapped).
    frames = {}
    base, last = 0, None
    for t_arr, kind, _seq, tms, _cells in packets:
        if kind != 1:
            continue
        if last is not None and tms < last and last - tms > 32768:
            base += 65536
        last = tms
        frames.setdefault(base + tms, t_arr)
    leads = []
    for ms, t_arr in sorted(frames.items()):
        p = ms / 1000.0 * RATE
        m = p + lag_at(p)
        if m >= len(y):
            continue
        leads.append((ms / 1000.0, (wall(m) - t_arr) * 1e3))
    steady = [v for s, v in leads if s >= args.settle]
    med = pct(steady, 0.5)
    dev = [v - med for v in steady]
    res = {
        "mode": "pattern" if args.pattern else "song",
        "play_exit": play_rc,
        "frames": len(leads),
        "frames_scored": len(steady),
        "settle_s": args.settle,
        "lead_ms": {"median": med, "p1": pct(steady, 0.01), "p5": pct(steady, 0.05),
                    "p95": pct(steady, 0.95), "p99": pct(steady, 0.99),
                    "min": min(steady), "max": max(steady)},
        "within_10ms_of_median": sum(1 for v in dev if abs(v) <= 10.0) / len(dev),
        "stated_lead_ms": args.stated_lead_ms,
        "within_10ms_of_stated": sum(1 for v in steady if abs(v - args.stated_lead_ms) <= 10.0)
        / len(steady),
        "max_abs_dev_ms": max(abs(v) for v in dev),
        "first_s_lead_ms": [round(v, 1) for s, v in leads if s < args.settle][:8],
        "lag_estimates": len(good),
        "lag_misses": len(lag) - len(good),
        "lag_changes": changes,
        "bad_crc": bad,
        "tactus_stderr": err.strip().splitlines()[-6:],
    }
    if args.trace:
        res["trace"] = [(round(s, 3), round(v, 2)) for s, v in leads]
    return res


def main():
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("song")
    ap.add_argument("--tactus", default="target/release/tactus")
    ap.add_argument("--pattern", help="play this pattern file (its song is SONG)")
    ap.add_argument("--settle", type=float, default=5.0,
                    help="seconds at the start not scored (PulseAudio's start, the clock's slew)")
    ap.add_argument("--stated-lead-ms", type=float, default=52.0,
                    help="the lead play states (50 ms pin rise + 2 ms for 16 bytes at 115200 baud)")
    ap.add_argument("--json")
    ap.add_argument("--trace", action="store_true", help="keep every frame's lead in the JSON")
    ap.add_argument("--from-debug", action="store_true",
                    help="analyse the last run saved with PLAY_SYNC_DEBUG=1 again")
    args = ap.parse_args(argv)
    try:
        import numpy as np
    except ImportError:
        print("play_sync: numpy is needed", file=sys.stderr)
        sys.exit(3)
    if args.from_debug:
        with open("/tmp/play_sync_packets.json") as f:
            d = json.load(f)
        stamps = [tuple(r) for r in np.load("/tmp/play_sync_stamps.npy")]
        res = analyse(args, np, d["packets"], d["bad"], np.load("/tmp/play_sync_rec.npy"),
                      stamps, d["err"], d["rc"])
    else:
        res = run(args, extra, np)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)
    r = {k: v for k, v in res.items() if k != "trace"}
    print(json.dumps(r, indent=1))


if __name__ == "__main__":
    main()

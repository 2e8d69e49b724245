#!/usr/bin/env python3
"""Speed against error: Tactus settings and Python peers on the same corpus, in one run.

    cargo build --release [--features onnx]
    python3 -m venv .venv-peers && .venv-peers/bin/pip install -r benches/peers/requirements.txt
    .venv-peers/bin/python benches/sweep.py [--quick] [--spleeter models/spleeter-2stems.onnx]

Tactus: `tactus render` over the corpus fixtures for each setting (input: isolated stems,
mix + spectral separator, mix + Spleeter unless --quick; offline / streaming statistics)
and each pipeline of SETTINGS: today's default (`--pitch auto`: the learned trackers on a
mixture's bass and lead, pYIN elsewhere; the per-instrument drum transcriber), the same
with the harmonic sum for bass and lead (`--pitch auto-shs`), and the paper's trackers
(pYIN, YIN) with its band-pass drums (`--drums bands`). Speed = song duration / wall time of the whole render process
(start-up, decode, separation, all features, files), best of --repeats.

Peers (isolated stems only, needs librosa / aubio / scipy; skipped if they do not import):
librosa.yin, librosa.pyin, aubio yin, aubio yinfft for pitch on the bass, vocals and other
stems (10 ms hops, Tactus's pitch ranges), and librosa onset_detect / aubio specflux for
onsets on the drum stem split into Tactus's four Butterworth bands (4th order, causal).
Their f0 and onsets go into a features-file-shaped JSON (levels: the truth's own binning
and 8-level discretization applied to the peer's f0, since peers have no level stage) and
are scored by the same `tactus eval`. Peer speed = duration / in-process time of
reading the stems, all pitch tracks, the band split and all onsets (no interpreter
start-up, numba JIT warmed up first), best of --repeats.

Writes benches/sweep.md (table), benches/sweep.svg (speed vs error, Pareto fronts) and
prints the table.
"""
import argparse, json, math, os, subprocess, sys, tempfile, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "tactus")
FIX = os.path.join(ROOT, "corpus", "fixtures")
SONGS = sorted(os.path.join(FIX, d) for d in os.listdir(FIX) if os.path.exists(os.path.join(FIX, d, "truth.json")))
BANDS = {"kick": (30.0, 150.0), "snare": (150.0, 800.0), "toms": (800.0, 5000.0), "cymbals": (5000.0, 12000.0)}
RANGES = {"bass": (35.0, 400.0), "vocals": (70.0, 1400.0), "other": (50.0, 2000.0)}
SR, HOP, ONSET_FRAME, ONSET_HOP = 44100, 441, 2048, 512


def best_of(fn, n):
    best = None
    for _ in range(n):
        t = time.perf_counter()
        fn()
        dt = time.perf_counter() - t
        best = dt if best is None else min(best, dt)
    return best


def scores(feat, song, tmp):
    ev = os.path.join(tmp, "e.json")
    subprocess.run([BIN, "eval", feat, "--truth", song, "--json", ev], check=True, stdout=subprocess.DEVNULL)
    e = json.load(open(ev))
    st = {r["stem"]: r for r in e["stems"]}
    return {
        "bass": st["bass"]["rpa"] or 0.0,
        "vocals": st["vocals"]["rpa"] or 0.0,
        "lvl": [st[s]["level_within_1"] or 0.0 for s in ("bass", "vocals")],
        "F": [b["f_measure"] or 0.0 for b in e["bands"]],
        "bandF": [b.get("band_f_measure") or 0.0 for b in e["bands"]],
    }


def aggregate(per_song, t, dur):
    m = lambda v: sum(v) / len(v)
    return {
        "speed": dur / t,
        "bass": m([s["bass"] for s in per_song]),
        "vocals": m([s["vocals"] for s in per_song]),
        "lvl": m([x for s in per_song for x in s["lvl"]]),
        "F": m([x for s in per_song for x in s["F"]]),
        "bandF": m([x for s in per_song for x in s["bandF"]]),
    }


# (--pitch, --drums, the onsets column): the default first, then the paper's pipeline.
SETTINGS = [
    ("auto", "classes", "drum transcriber"),
    ("auto-shs", "classes", "drum transcriber"),
    ("pyin", "bands", "bands + spectral flux"),
    ("yin", "bands", "bands + spectral flux"),
]


def tactus_rows(a, tmp):
    rows = []
    seps = ["stems", "spectral"] + (["spleeter"] if a.spleeter and not a.quick else [])
    for sep in seps:
        for pitch, drums, onsets in SETTINGS:
            for mode in ["offline", "streaming"]:
                per, t, dur = [], 0.0, 0.0
                for song in SONGS:
                    feat = os.path.join(tmp, "f.json")
                    args = ["render", os.path.join(song, "mix.flac"), "--pitch", pitch, "--drums", drums,
                            "--mode", mode, "--features", feat]
                    if sep == "stems":
                        for s in ["drums", "bass", "vocals", "other"]:
                            args += ["--stem", f"{s}={os.path.join(song, s + '.flac')}"]
                    elif sep == "spleeter":
                        args += ["--separator", "spleeter", "--model", a.spleeter]
                    t += best_of(lambda: subprocess.run([BIN] + args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), a.repeats)
                    dur += json.load(open(os.path.join(song, "truth.json")))["duration_s"]
                    per.append(scores(feat, song, tmp))
                name = {"stems": "isolated stems", "spectral": "mix, spectral", "spleeter": "mix, Spleeter ONNX"}[sep]
                r = dict(aggregate(per, t, dur), who="Tactus", input=name, pitch=pitch, onsets=onsets, stats=mode)
                print(r, file=sys.stderr, flush=True)
                rows.append(r)
    return rows


# ---------------------------------------------------------------------------------------
# Peers


def truth_levels(f0, hop_s, bin_s=0.1, levels=8):
    """tactus-eval's levels.rs rules: bin (lower median of voiced if >= half voiced), then
    8 equal-width semitone steps over the voiced range."""
    import numpy as np
    n = int(math.floor((len(f0) - 1) * hop_s / bin_s + 1e-9)) + 1 if len(f0) else 0
    out = []
    for k in range(n):
        idx = [i for i in range(len(f0)) if math.floor(i * hop_s / bin_s + 1e-9) == k]
        v = sorted(f0[i] for i in idx if f0[i] > 0)
        out.append(v[(len(v) - 1) // 2] if v and 2 * len(v) >= len(idx) else 0.0)
    st = [69 + 12 * math.log2(f / 440.0) for f in out if f > 0]
    if not st:
        return [0] * n
    lo, hi = min(st), max(st)
    res = []
    for f in out:
        if f <= 0:
            res.append(0)
        elif hi > lo:
            x = (69 + 12 * math.log2(f / 440.0) - lo) / (hi - lo) * levels
            res.append(int(min(1 + math.floor(x), levels)))
        else:
            res.append(1)
    return res


def peer_rows(a, tmp):
    try:
        import numpy as np
        import soundfile as sf
        import librosa
        import scipy.signal as ss
    except Exception as e:  # pragma: no cover
        print(f"peers skipped: {e!r}", file=sys.stderr)
        return []
    try:
        import aubio
    except Exception:
        aubio = None

    def lib_yin(x, lo, hi, frame):
        return librosa.yin(x, fmin=lo, fmax=hi, sr=SR, frame_length=frame, hop_length=HOP)

    def lib_pyin(x, lo, hi, frame):
        f0, voiced, _ = librosa.pyin(x, fmin=lo, fmax=hi, sr=SR, frame_length=frame, hop_length=HOP)
        return np.where(voiced, np.nan_to_num(f0), 0.0)

    def aubio_pitch(method):
        def run(x, lo, hi, frame):
            p = aubio.pitch(method, frame, HOP, SR)
            p.set_unit("Hz")
            # Centre the analysis window on hop i, as librosa's centred frames.
            pad = np.concatenate([np.zeros(frame // 2 - HOP, dtype=np.float32), x.astype(np.float32),
                                  np.zeros(frame, dtype=np.float32)])
            n = int(math.ceil(len(x) / HOP))
            out = np.empty(n)
            for i in range(n):
                out[i] = p(pad[i * HOP:(i + 1) * HOP])[0]
            return np.where((out >= lo) & (out <= hi), out, 0.0)
        return run

    def lib_onsets(x):
        return librosa.onset.onset_detect(y=x, sr=SR, hop_length=ONSET_HOP, units="time")

    def aubio_onsets(x):
        o = aubio.onset("specflux", ONSET_FRAME, ONSET_HOP, SR)
        x = np.concatenate([x.astype(np.float32), np.zeros(ONSET_HOP, dtype=np.float32)])
        hits = []
        for i in range(len(x) // ONSET_HOP):
            if o(x[i * ONSET_HOP:(i + 1) * ONSET_HOP])[0]:
                hits.append(o.get_last_s())
        return hits

    sos = {b: ss.butter(4, edges, "bandpass", fs=SR, output="sos") for b, edges in BANDS.items()}
    combos = [("librosa", "librosa.yin", lib_yin, "librosa onset_detect", lib_onsets),
              ("librosa", "librosa.pyin", lib_pyin, "librosa onset_detect", lib_onsets)]
    if aubio is not None:
        combos += [("aubio", "aubio yin", aubio_pitch("yin"), "aubio specflux", aubio_onsets),
                   ("aubio", "aubio yinfft", aubio_pitch("yinfft"), "aubio specflux", aubio_onsets)]
    # numba JIT warm-up
    z = np.random.default_rng(0).standard_normal(SR).astype(np.float32) * 0.1
    lib_yin(z, 70, 1400, 2048), lib_pyin(z, 70, 1400, 2048), lib_onsets(z)
    rows = []
    for who, pname, pfn, oname, ofn in combos:
        per, t, dur = [], 0.0, 0.0
        for song in SONGS:
            result = {}

            def work():
                stems = {s: sf.read(os.path.join(song, s + ".flac"), dtype="float32")[0] for s in ("drums", "bass", "vocals", "other")}
                pitch = {}
                for s, (lo, hi) in RANGES.items():
                    pitch[s] = pfn(stems[s], lo, hi, 4096 if s == "bass" else 2048)
                onsets = {b: [float(v) for v in ofn(ss.sosfilt(sos[b], stems["drums"]).astype(np.float32))] for b in BANDS}
                result.update(pitch=pitch, onsets=onsets)

            t += best_of(work, a.repeats)
            dur += json.load(open(os.path.join(song, "truth.json")))["duration_s"]
            feat = {"hop_s": HOP / SR, "bin_s": 0.1,
                    "pitch_hz": {s: [float(v) for v in f] for s, f in result["pitch"].items()},
                    "levels": {s: truth_levels([float(v) for v in f], HOP / SR) for s, f in result["pitch"].items()},
                    "onsets_s": result["onsets"]}
            fp = os.path.join(tmp, "peer.json")
            json.dump(feat, open(fp, "w"))
            per.append(scores(fp, song, tmp))
        r = dict(aggregate(per, t, dur), who=who, input="isolated stems", pitch=pname, onsets=oname, stats="offline")
        print(r, file=sys.stderr, flush=True)
        rows.append(r)
    return rows


# ---------------------------------------------------------------------------------------
# Outputs


def pareto(points):
    """Indices of points not dominated (higher speed and lower error is better)."""
    keep = []
    for i, (s, e) in enumerate(points):
        if not any((s2 >= s and e2 <= e) and (s2 > s or e2 < e) for j, (s2, e2) in enumerate(points) if j != i):
            keep.append(i)
    return sorted(keep, key=lambda i: points[i][0])


def label(r):
    if r["who"] == "Tactus":
        return f"{r['input']}, {r['pitch']}, {r['stats']}"
    return f"{r['pitch']} + {r['onsets']}"


def markdown(rows, cmd):
    ref = next((r for r in rows if r["who"] == "Tactus" and r["input"] == "isolated stems" and r["pitch"] == "auto" and r["stats"] == "offline"), rows[0])
    err_rpa = [(r["speed"], 1 - (r["bass"] + r["vocals"]) / 2) for r in rows]
    err_f = [(r["speed"], 1 - r["bandF"]) for r in rows]
    front_rpa, front_f = set(pareto(err_rpa)), set(pareto(err_f))
    s = [f"Generated by `{cmd}`; {len(SONGS)} fixture songs ({', '.join(os.path.basename(x) for x in SONGS)}).",
         "Speed relative to Tactus's default (`--pitch auto`, drum transcriber) on isolated stems, offline statistics. RPA: raw pitch accuracy (±50 cents);",
         "level ±1: bass + vocals tactile levels within one of the truth's; onset F within ±50 ms, mean of 4 bands,",
         "against the per-instrument and the per-band truth. front: on the Pareto front of speed vs 1 − mean RPA (RPA) or vs 1 − band onset F (F).", "",
         "| # | who | input | pitch | onsets | stats | speed (× real time) | speed ratio | bass RPA | vocals RPA | level ±1 | onset F instrument | onset F band | front |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for i, r in enumerate(rows):
        front = ("RPA" if i in front_rpa else "") + (" F" if i in front_f else "")
        s.append(f"| {i + 1} | {r['who']} | {r['input']} | {r['pitch']} | {r['onsets']} | {r['stats']} | {r['speed']:.1f}× | {r['speed'] / ref['speed']:.2f} | "
                 f"{r['bass']:.3f} | {r['vocals']:.3f} | {r['lvl']:.3f} | {r['F']:.3f} | {r['bandF']:.3f} | {front.strip() or ''} |")
    return "\n".join(s) + "\n"


def svg(rows):
    W, H, M = 1100, 520, 60
    pw = (W - 3 * M) / 2
    colors = {"Tactus": "#1f6fb4", "librosa": "#d9822b", "aubio": "#3a9a3a"}
    speeds = [r["speed"] for r in rows]
    x0, x1 = 10 ** math.floor(math.log10(min(speeds))), 10 ** math.ceil(math.log10(max(speeds)))
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="10">',
           f'<rect width="{W}" height="{H}" fill="white"/>']
    panels = [("1 − mean RPA (bass, vocals)", lambda r: 1 - (r["bass"] + r["vocals"]) / 2),
              ("1 − onset F (per-band truth)", lambda r: 1 - r["bandF"])]
    for p, (title, err) in enumerate(panels):
        left = M + p * (pw + M)
        top, bottom = 40, H - M
        errs = [err(r) for r in rows]
        ymax = max(0.05, math.ceil(max(errs) * 10 + 0.5) / 10)
        X = lambda s: left + (math.log10(s) - math.log10(x0)) / (math.log10(x1) - math.log10(x0)) * pw
        Y = lambda e: bottom - e / ymax * (bottom - top)
        out.append(f'<text x="{left + pw / 2}" y="22" text-anchor="middle" font-size="13">{title} against speed</text>')
        out.append(f'<rect x="{left}" y="{top}" width="{pw}" height="{bottom - top}" fill="none" stroke="#444"/>')
        d = x0
        while d <= x1 * 1.0001:
            for m in range(1, 10):
                v = d * m
                if v > x1 * 1.0001:
                    break
                out.append(f'<line x1="{X(v):.1f}" y1="{top}" x2="{X(v):.1f}" y2="{bottom}" stroke="#eee"/>')
            out.append(f'<text x="{X(d):.1f}" y="{bottom + 14}" text-anchor="middle">{d:g}×</text>')
            d *= 10
        for k in range(6):
            e = ymax * k / 5
            out.append(f'<text x="{left - 6}" y="{Y(e) + 3:.1f}" text-anchor="end">{e:.2f}</text>')
            out.append(f'<line x1="{left}" y1="{Y(e):.1f}" x2="{left + pw}" y2="{Y(e):.1f}" stroke="#eee"/>')
        out.append(f'<text x="{left + pw / 2}" y="{H - 20}" text-anchor="middle">speed (× real time, log scale)</text>')
        front = pareto([(r["speed"], err(r)) for r in rows])
        pts = " ".join(f"{X(rows[i]['speed']):.1f},{Y(err(rows[i])):.1f}" for i in front)
        out.append(f'<polyline points="{pts}" fill="none" stroke="#c00" stroke-width="1.5" stroke-dasharray="5,3"/>')
        for i, r in enumerate(rows):
            x, y = X(r["speed"]), Y(err(r))
            c = colors.get(r["who"], "#666")
            ring = ' stroke="#c00" stroke-width="2"' if i in front else ""
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{c}"{ring}/>')
            # Row numbers of benches/sweep.md keep the labels legible where points crowd;
            # points on the front also get their name.
            name = f" {label(r)}" if i in front else ""
            # Names near the right edge go to the left of their point.
            anchor, dx = ("end", -6) if name and x > left + 0.6 * pw else ("start", 6)
            out.append(f'<text x="{x + dx:.1f}" y="{y - 4 - 9 * (i % 2):.1f}" fill="{c}" font-size="9" text-anchor="{anchor}">{i + 1}{name}</text>')
    ly = H - 8
    for k, (who, c) in enumerate(colors.items()):
        out.append(f'<circle cx="{M + 140 * k}" cy="{ly - 3}" r="4" fill="{c}"/><text x="{M + 8 + 140 * k}" y="{ly}">{who}</text>')
    out.append(f'<line x1="{M + 430}" y1="{ly - 3}" x2="{M + 460}" y2="{ly - 3}" stroke="#c00" stroke-dasharray="5,3"/><text x="{M + 466}" y="{ly}">Pareto front (ringed points); numbers are the rows of benches/sweep.md</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spleeter", help="Spleeter ONNX model (needs a build with --features onnx)")
    ap.add_argument("--quick", action="store_true", help="skip Spleeter")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--replot", action="store_true", help="redraw benches/sweep.svg from benches/sweep.json without running anything")
    a = ap.parse_args()
    json_path = os.path.join(ROOT, "benches", "sweep.json")
    if a.replot:
        rows = json.load(open(json_path))
        open(os.path.join(ROOT, "benches", "sweep.svg"), "w").write(svg(rows))
        return
    cmd = "python3 benches/sweep.py" + (" --quick" if a.quick else "") + (f" --spleeter {a.spleeter}" if a.spleeter and not a.quick else "")
    with tempfile.TemporaryDirectory() as tmp:
        rows = tactus_rows(a, tmp) + ([] if a.no_peers else peer_rows(a, tmp))
    md = markdown(rows, cmd)
    load = os.getloadavg()
    md += f"\nLoad average at the end: {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} ({os.cpu_count()} cores); best of {a.repeats}.\n"
    open(os.path.join(ROOT, "benches", "sweep.md"), "w").write(md)
    open(os.path.join(ROOT, "benches", "sweep.svg"), "w").write(svg(rows))
    json.dump(rows, open(json_path, "w"), indent=1)
    print(md)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Speed against error: runs `tactus render` over the corpus fixtures for each setting and
scores it with `tactus eval`. Prints a Markdown table (the one in README.md).

    cargo build --release [--features onnx]
    python3 benches/sweep.py [--spleeter models/spleeter-2stems.onnx]

Speed is the song duration over the wall time of the whole render (decode, separation,
all features, pattern and features files), best of 3, on this machine.
"""
import argparse, json, os, subprocess, sys, tempfile, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "tactus")
SONGS = sorted(os.path.join(ROOT, "corpus", "fixtures", d) for d in os.listdir(os.path.join(ROOT, "corpus", "fixtures")))


def run(args):
    best = None
    for _ in range(3):
        t = time.perf_counter()
        subprocess.run([BIN] + args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        dt = time.perf_counter() - t
        best = dt if best is None else min(best, dt)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spleeter")
    a = ap.parse_args()
    settings = []
    for sep in ["stems", "spectral"] + (["spleeter"] if a.spleeter else []):
        for pitch in ["yin", "pyin"]:
            for mode in ["offline", "streaming"]:
                settings.append((sep, pitch, mode))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for sep, pitch, mode in settings:
            agg = {"bass": [], "vocals": [], "lvl": [], "F": [], "t": 0.0, "dur": 0.0}
            for song in SONGS:
                feat, ev = os.path.join(tmp, "f.json"), os.path.join(tmp, "e.json")
                args = ["render", os.path.join(song, "mix.flac"), "--pitch", pitch, "--mode", mode, "--features", feat]
                if sep == "stems":
                    for s in ["drums", "bass", "vocals", "other"]:
                        args += ["--stem", f"{s}={os.path.join(song, s + '.flac')}"]
                elif sep == "spleeter":
                    args += ["--separator", "spleeter", "--model", a.spleeter]
                agg["t"] += run(args)
                truth = json.load(open(os.path.join(song, "truth.json")))
                agg["dur"] += truth["duration_s"]
                subprocess.run([BIN, "eval", feat, "--truth", song, "--json", ev], check=True, stdout=subprocess.DEVNULL)
                e = json.load(open(ev))
                st = {r["stem"]: r for r in e["stems"]}
                agg["bass"].append(st["bass"]["rpa"])
                agg["vocals"].append(st["vocals"]["rpa"])
                agg["lvl"] += [st[s]["level_within_1"] for s in ("bass", "vocals")]
                agg["F"] += [b["f_measure"] for b in e["bands"]]
            m = lambda v: sum(v) / len(v)
            rows.append((sep, pitch, mode, agg["dur"] / agg["t"], m(agg["bass"]), m(agg["vocals"]), m(agg["lvl"]), m(agg["F"])))
            print(rows[-1], file=sys.stderr)
    print("| input | pitch | stats | speed (× real time) | bass RPA | vocals RPA | bass+vocals level ±1 | drum onset F (4 bands) |")
    print("|---|---|---|---|---|---|---|---|")
    for sep, pitch, mode, x, b, v, l, f in rows:
        name = {"stems": "isolated stems (`--stem`)", "spectral": "mix, spectral (default)", "spleeter": "mix, Spleeter ONNX"}[sep]
        print(f"| {name} | {pitch} | {mode} | {x:.0f}× | {b:.3f} | {v:.3f} | {l:.3f} | {f:.3f} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Melodic-stem scores (bass and vocals) of one tactus binary on corpus songs, as a table.

For every song folder (`mix.*`, stems, `truth.json`, as written by corpus/generate.py or
corpus/drums.py) and every input (isolated stems / the mix through the default separator)
and statistics mode, runs

    tactus render SONG/mix.* -o P.json --features F.json [--stem NAME=SONG/NAME.* ...] --mode M [EXTRA]
    tactus eval F.json --truth SONG --json R.json

and prints the mean over songs, per group (tuned / held-out), of RPA, levels ±1 and
note-onset F for bass and vocals. Raw per-song rows go to OUT/rows.json.

Inputs: `isolated` (every stem given with --stem), `mix` (the mix through the default
separator) and `nodrums`, a diagnosis: the mix minus its drum stem (16-bit PCM WAV songs,
written to OUT), through the default separator, i.e. what the melodic stems would score if
the kit were not there.

    python3 benches/bass_eval.py --bin target/release/tactus --out /tmp/be \\
        --tuned /work/data/chorales/bwv66-6_96bpm ... --held-out /work/data/chorales/bwv7-7_84bpm ... \\
        [--extra "--pitch yin"] [--label before]
"""
import argparse
import glob
import json
import os
import shlex
import subprocess
import sys
import threading
import wave

import numpy as np

STEMS = ("drums", "bass", "vocals", "other")
METRICS = (("bass", "rpa"), ("bass", "level_within_1"), ("bass", "note_f_measure"),
           ("vocals", "rpa"), ("vocals", "level_within_1"), ("vocals", "note_f_measure"),
           ("vocals", "voicing_recall"), ("vocals", "voicing_false_alarm"))


def audio(song, name):
    for ext in ("wav", "flac", "mp3", "ogg"):
        p = os.path.join(song, f"{name}.{ext}")
        if os.path.exists(p):
            return p
    return None


def read_pcm16(path):
    with wave.open(path, "rb") as w:
        if w.getsampwidth() != 2:
            raise SystemExit(f"{path}: nodrums needs 16-bit PCM WAV")
        return w.getparams(), np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")


def without_drums(song, dst):
    """Writes the song's mix minus its drum stem to `dst` (16-bit PCM), once."""
    if os.path.exists(dst):
        return dst
    mp, mix = read_pcm16(audio(song, "mix"))
    dp, drums = read_pcm16(audio(song, "drums"))
    if (mp.nchannels, mp.framerate) != (dp.nchannels, dp.framerate):
        raise SystemExit(f"{song}: mix and drums differ in channels or rate")
    n = min(len(mix), len(drums))
    y = np.clip(mix[:n].astype(np.int32) - drums[:n], -32768, 32767).astype("<i2")
    tmp = f"{dst}.{os.getpid()}.{threading.get_ident()}.tmp"
    with wave.open(tmp, "wb") as w:
        w.setnchannels(mp.nchannels)
        w.setsampwidth(2)
        w.setframerate(mp.framerate)
        w.writeframes(y.tobytes())
    os.replace(tmp, dst)
    return dst


def run_one(binary, song, inp, mode, extra, out, eval_bin=None):
    parent = os.path.basename(os.path.dirname(song.rstrip("/")))
    name = f"{parent}_{os.path.basename(song.rstrip('/'))}"
    tag = f"{name}.{inp}.{mode}"
    feat = os.path.join(out, tag + ".features.json")
    rep = os.path.join(out, tag + ".report.json")
    src = audio(song, "mix")
    if inp == "nodrums":
        src = without_drums(song, os.path.join(out, name + ".nodrums.wav"))
    cmd = [binary, "render", src, "-o", os.path.join(out, tag + ".pattern.json"),
           "--features", feat, "--mode", mode] + extra
    if inp == "isolated":
        for s in STEMS:
            p = audio(song, s)
            if p:
                cmd += ["--stem", f"{s}={p}"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    subprocess.run([eval_bin or binary, "eval", feat, "--truth", song, "--json", rep], check=True,
                   stdout=subprocess.DEVNULL)
    with open(rep) as fh:
        r = json.load(fh)
    row = {"song": r["song"], "input": inp, "mode": mode}
    for st in r["stems"]:
        for _s, m in METRICS:
            if st["stem"] == _s:
                row[f"{_s}.{m}"] = st.get(m)
    return row


def mean(v):
    v = [x for x in v if x is not None]
    return sum(v) / len(v) if v else None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release/tactus")
    ap.add_argument("--eval-bin", default=None, help="binary for `tactus eval` (default: --bin)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--tuned", nargs="*", default=[])
    ap.add_argument("--held-out", nargs="*", default=[])
    ap.add_argument("--inputs", default="isolated,mix")
    ap.add_argument("--modes", default="offline,streaming")
    ap.add_argument("--extra", default="", help="extra render options, one string")
    ap.add_argument("--label", default="")
    ap.add_argument("--per-song", action="store_true")
    ap.add_argument("--jobs", type=int, default=1, help="renders run in parallel")
    a = ap.parse_args()
    bad = set(a.inputs.split(",")) - {"isolated", "mix", "nodrums"}
    if bad:
        ap.error(f"unknown --inputs {','.join(sorted(bad))} (isolated, mix, nodrums)")
    os.makedirs(a.out, exist_ok=True)
    extra = shlex.split(a.extra)
    rows = []
    groups = [("tuned", s) for s in a.tuned] + [("held-out", s) for s in a.held_out]
    tasks = [(group, song, inp, mode) for group, song in groups for inp in a.inputs.split(",")
             for mode in a.modes.split(",")]

    def one(t):
        group, song, inp, mode = t
        r = run_one(a.bin, song, inp, mode, extra, a.out, a.eval_bin)
        r["group"] = group
        return r

    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(max(1, a.jobs)) as ex:
        rows = list(ex.map(one, tasks))
    with open(os.path.join(a.out, "rows.json"), "w") as fh:
        json.dump(rows, fh, indent=1)
    hdr = "| " + " | ".join(["label", "group", "songs", "input", "mode"] +
                            [f"{s} {m.replace('level_within_1', 'levels ±1').replace('note_f_measure', 'note F').replace('rpa', 'RPA').replace('voicing_recall', 'voicing R').replace('voicing_false_alarm', 'voicing FA')}"
                             for s, m in METRICS]) + " |"
    print(hdr)
    print("|" + "---|" * (5 + len(METRICS)))
    for group in ("tuned", "held-out"):
        for inp in a.inputs.split(","):
            for mode in a.modes.split(","):
                sel = [r for r in rows if r["group"] == group and r["input"] == inp and r["mode"] == mode]
                if not sel:
                    continue
                cells = [mean([r.get(f"{s}.{m}") for r in sel]) for s, m in METRICS]
                print("| " + " | ".join([a.label, group, str(len(sel)), inp, mode] +
                                        ["–" if c is None else f"{c:.3f}" for c in cells]) + " |")
    if a.per_song:
        print()
        for r in rows:
            print(r["group"], r["song"], r["input"], r["mode"],
                  " ".join(f"{k}={r.get(k) if r.get(k) is None else round(r[k], 3)}" for k in (f"{s}.{m}" for s, m in METRICS)))


if __name__ == "__main__":
    sys.exit(main())

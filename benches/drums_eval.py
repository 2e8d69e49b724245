#!/usr/bin/env python3
"""Per-instrument drum transcription scores on the drums corpus (corpus/drums.py), issue 10.

For every song folder under --data (<family>/<song>/{mix,drums}.wav + truth.json) and every
method, runs the release binary in two conditions:

  isolated  tactus render SONG/mix.wav --stem drums=SONG/drums.wav --map drums-only.toml --features F.json ARGS
  mix       tactus render SONG/mix.wav --features F.json ARGS            (default map, default separator)

then `tactus eval F.json --truth SONG --json E.json`. Per class (kick, snare, toms, cymbals)
TP/FP/FN are summed over songs and P/R/F computed from the sums, per family and for the
held-out and training splits. In Python, from the features file's onsets_s and truth.json
(same +-50 ms maximum matching as tactus-eval, cross-checked against its counts):

* FP confusion: each unmatched detection of class c is attributed to the nearest true onset
  of another class within +-50 ms ("near kick" ...), else "double" if a true onset of c
  itself is that close (a second detection of one hit), else "nothing";
* FN confusion: each missed true onset of c: the nearest detection of another class within
  +-50 ms ("heard as ..."), else "silent";
* recall by hit type: backbeat vs ghost snare (velocity <= 45), rim 37, closed / pedal /
  open hat, ride, crash-like, toms.
* per finger (what the glove says): the index finger's onsets are the union of the kick's
  and the snare's, the middle finger's of the toms' and the cymbals' (onsets closer than
  30 ms count once, as the truth's hits of one class do), matched to the union of the same
  classes' true onsets: a kick called on a snare still raises the right finger, a tom
  called on a snare does not.

Methods are free-form argument strings appended to both renders:
    --method bands="--drums bands" --method embedded="" --method adtlib="--drums adtlib --drum-model X"
Without --method, one method "default" with no extra arguments.

    python3 benches/drums_eval.py --data /work/data/drums [--bin target/release/tactus]
        [--held-out musescore] [--method NAME=ARGS]... [--conditions isolated,mix]
        [--families a,b] [--jobs 2] [--out benches/drums_eval]   # writes OUT.md and OUT.json

Only the standard library is needed.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import shlex
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLASSES = ("kick", "snare", "toms", "cymbals")
WINDOW_S = 0.05
DRUMS_ONLY_MAP = os.path.join(ROOT, "crates", "tactus-glove", "maps", "drums-only.toml")
SUBTYPES = [
    ("kick", "kick", lambda h: True),
    ("snare backbeat (v>45)", "snare", lambda h: h["note"] in (38, 40) and h["velocity"] > 45),
    ("snare ghost (v<=45)", "snare", lambda h: h["note"] in (38, 40) and h["velocity"] <= 45),
    ("rim 37", "snare", lambda h: h["note"] == 37),
    ("toms", "toms", lambda h: True),
    ("closed hat 42", "cymbals", lambda h: h["note"] == 42),
    ("pedal hat 44", "cymbals", lambda h: h["note"] == 44),
    ("open hat 46", "cymbals", lambda h: h["note"] == 46),
    ("ride 51/53", "cymbals", lambda h: h["note"] in (51, 53, 59)),
    ("crash/splash/china", "cymbals", lambda h: h["note"] in (49, 52, 55, 57)),
]


def match(ref, est, w=WINDOW_S):
    """Maximum matching of sorted ref and est times within +-w (Glover's greedy for convex
    bipartite graphs: each ref, in order, takes the earliest free estimate in its window).
    Returns (matched ref indices, matched est indices)."""
    used = [False] * len(est)
    mref, mest = set(), set()
    j0 = 0
    for i, r in enumerate(ref):
        while j0 < len(est) and not r <= est[j0] + w:  # tactus-eval's bounds: e - w <= r <= e + w
            j0 += 1
        j = j0
        while j < len(est) and est[j] - w <= r:
            if not used[j]:
                used[j] = True
                mref.add(i)
                mest.add(j)
                break
            j += 1
    return mref, mest


def nearest(t, times, w=WINDOW_S):
    best = None
    for u in times:
        d = abs(u - t)
        if u - w <= t <= u + w and (best is None or d < best):
            best = d
    return best


FINGERS = (("index", ("kick", "snare")), ("middle", ("toms", "cymbals")))
MERGE_S = 0.03  # onsets of one finger closer than this count once (truth.json's onsets_rule)


def merged(times, gap=MERGE_S):
    """Sorted times with those less than `gap` after the previous kept one dropped."""
    out = []
    for t in sorted(times):
        if not out or t - out[-1] >= gap:
            out.append(t)
    return out


def finger_counts(est, ref):
    """TP / FP / FN of each finger: its classes' onsets merged, matched one to one (±50 ms)."""
    out = {}
    for finger, classes in FINGERS:
        e = merged([t for c in classes for t in est[c]])
        r = merged([t for c in classes for t in ref[c]])
        mref, mest = match(r, e)
        out[finger] = {"tp": len(mref), "fp": len(e) - len(mest), "fn": len(r) - len(mref)}
    return out


def analyse(features, truth):
    """Python-side per-class matching, confusion and subtype recall for one song."""
    est = {c: sorted(features.get("onsets_s", {}).get(c, []) or []) for c in CLASSES}
    tr = {c: sorted(truth["onsets"].get(c, []), key=lambda h: h["time_s"]) for c in CLASSES}
    ref = {c: [h["time_s"] for h in tr[c]] for c in CLASSES}
    out = {"counts": {}, "fp_near": {}, "fn_heard": {}, "subtype": {}, "finger": finger_counts(est, ref)}
    for c in CLASSES:
        mref, mest = match(ref[c], est[c])
        out["counts"][c] = {"tp": len(mref), "fp": len(est[c]) - len(mest), "fn": len(ref[c]) - len(mref)}
        near = {k: 0 for k in list(CLASSES) + ["double", "nothing"]}
        for j, e in enumerate(est[c]):
            if j in mest:
                continue
            cand = [(nearest(e, ref[o]), o) for o in CLASSES if o != c]
            cand = [x for x in cand if x[0] is not None]
            if cand:
                near[min(cand)[1]] += 1
            elif nearest(e, ref[c]) is not None:
                near["double"] += 1
            else:
                near["nothing"] += 1
        out["fp_near"][c] = near
        heard = {k: 0 for k in list(CLASSES) + ["silent"]}
        for i, r in enumerate(ref[c]):
            if i in mref:
                continue
            cand = [(nearest(r, est[o]), o) for o in CLASSES if o != c]
            cand = [x for x in cand if x[0] is not None]
            heard[min(cand)[1] if cand else "silent"] += 1
        out["fn_heard"][c] = heard
        for name, cls, pred in SUBTYPES:
            if cls != c:
                continue
            idx = [i for i, h in enumerate(tr[c]) if pred(h)]
            out["subtype"][name] = {"n": len(idx), "hit": sum(1 for i in idx if i in mref)}
    return out


def run_one(job):
    song, cond, method, margs, binary, mix_map = job
    tmp = tempfile.mkdtemp(prefix="tactus-drums-eval-")
    feat, ev = os.path.join(tmp, "f.json"), os.path.join(tmp, "e.json")
    try:
        cmd = [binary, "render", os.path.join(song, "mix.wav"), "--features", feat]
        if cond == "isolated":
            cmd += ["--stem", "drums=" + os.path.join(song, "drums.wav"), "--map", DRUMS_ONLY_MAP]
        elif mix_map:
            cmd += ["--map", mix_map]
        cmd += shlex.split(margs)
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            return {"song": song, "cond": cond, "method": method, "error": (r.stderr or r.stdout).strip()[-400:],
                    "cmd": " ".join(shlex.quote(x) for x in cmd)}
        r = subprocess.run([binary, "eval", feat, "--truth", song, "--json", ev], capture_output=True, text=True)
        if r.returncode != 0:
            return {"song": song, "cond": cond, "method": method, "error": "eval: " + r.stderr.strip()[-400:]}
        e = json.load(open(ev))
        features = json.load(open(feat))
        truth = json.load(open(os.path.join(song, "truth.json")))
        py = analyse(features, truth)
        tactus = {}
        for b in e["bands"]:
            c = b["band"]
            n_ref, n_est = b["truth_onsets"], b["est_onsets"] or 0
            if b["recall"] is not None and n_ref:
                tp = round(b["recall"] * n_ref)
            elif b["precision"] is not None and n_est:
                tp = round(b["precision"] * n_est)
            else:
                tp = 0
            tactus[c] = {"tp": tp, "fp": n_est - tp, "fn": n_ref - tp}
        mismatch = {c: (tactus[c], py["counts"][c]) for c in CLASSES if tactus.get(c) != py["counts"][c]}
        return {"song": song, "cond": cond, "method": method, "family": truth.get("family", os.path.basename(os.path.dirname(song))),
                "counts": tactus, "py": py, "mismatch": mismatch, "wall_s": wall, "duration_s": truth["duration_s"]}
    finally:
        for f in (feat, ev):
            if os.path.exists(f):
                os.remove(f)
        os.rmdir(tmp)


def prf(tp, fp, fn):
    p = tp / (tp + fp) if tp + fp else None
    r = tp / (tp + fn) if tp + fn else None
    f = 2 * p * r / (p + r) if p is not None and r is not None and p + r > 0 else (0.0 if p is not None and r is not None else None)
    return p, r, f


def fmt(x):
    return "–" if x is None else f"{x:.3f}"


def add(dst, src):
    for k, v in src.items():
        if isinstance(v, dict):
            add(dst.setdefault(k, {}), v)
        else:
            dst[k] = dst.get(k, 0) + v


def aggregate(results):
    """{(method, cond): {"split": {held_out|training: agg}, "family": {fam: agg}}}."""
    agg = {}
    for r in results:
        if "error" in r:
            continue
        key = (r["method"], r["cond"])
        a = agg.setdefault(key, {"split": {}, "family": {}})
        for group in (("split", r["split"]), ("family", r["family"])):
            g = a[group[0]].setdefault(group[1], {"songs": 0, "wall_s": 0.0, "duration_s": 0.0})
            g["songs"] += 1
            g["wall_s"] += r["wall_s"]
            g["duration_s"] += r["duration_s"]
            add(g, {"counts": r["counts"], "fp_near": r["py"]["fp_near"], "fn_heard": r["py"]["fn_heard"],
                    "subtype": r["py"]["subtype"], "finger": r["py"]["finger"]})
    for a in agg.values():
        for groups in a.values():
            for g in groups.values():
                g["scores"] = {c: dict(zip(("p", "r", "f"), prf(g["counts"][c]["tp"], g["counts"][c]["fp"], g["counts"][c]["fn"])))
                               for c in CLASSES}
                g["finger_scores"] = {k: dict(zip(("p", "r", "f"), prf(v["tp"], v["fp"], v["fn"])))
                                      for k, v in g["finger"].items()}
    return agg


def song_list(songs, data):
    """`family: first .. last (n of N folders)` per family: `--songs N` takes the first N
    folders in sorted order, so two reports score the same songs only if each family holds
    the same folders (README's held-out figures need `fluid` generated with 40 songs)."""
    by = {}
    for s in songs:
        by.setdefault(os.path.basename(os.path.dirname(s)), []).append(os.path.basename(s))
    out = []
    for fam, names in by.items():
        total = sum(1 for d in os.listdir(os.path.join(data, fam)) if not d.startswith("."))
        out.append(f"{fam}: {names[0]} .. {names[-1]} ({len(names)} of {total} folders)")
    return "; ".join(out)


def present(a, splits):
    """(split, its aggregate) for the splits a method-condition has songs in, in order."""
    return [(sp, a["split"][sp]) for sp in splits if a["split"].get(sp)]


def markdown(agg, args, methods, n_songs, errors, mismatches, songs=()):
    L = []
    L.append("# Drum transcription: per-instrument onset scores\n")
    L.append(f"Data: `{args.data}` ({n_songs} songs); held out: {', '.join(args.held_out) or 'none'}; "
             f"window ±{WINDOW_S * 1000:.0f} ms; TP/FP/FN summed over songs, then P/R/F.")
    if songs:
        L.append(f"Songs (the first `--songs` folders of each family, sorted): {song_list(songs, args.data)}.")
    L.append("Conditions: **isolated** = `render mix.wav --stem drums=drums.wav --map drums-only.toml`; "
             "**mix** = `render mix.wav` (default map and separator).")
    L.append("Methods: " + ", ".join(f"`{m}` = `{a or '(no extra args)'}`" for m, a in methods) + "\n")
    if errors:
        L.append(f"**{len(errors)} runs failed**, first: `{errors[0]['song']}` {errors[0]['cond']} {errors[0]['method']}: {errors[0]['error']}\n")
    if mismatches:
        L.append(f"Note: Python matching differs from tactus eval's counts on {mismatches} song-runs.\n")
    splits = ["held_out", "training"]
    for (m, cond), a in sorted(agg.items(), key=lambda kv: (kv[0][0], kv[0][1] != "isolated")):
        L.append(f"## {m}, {cond}\n")
        L.append("| split | songs | class | TP | FP | FN | P | R | F |")
        L.append("|---|---|---|---|---|---|---|---|---|")
        for sp, g in present(a, splits):
            for c in CLASSES:
                k, s = g["counts"][c], g["scores"][c]
                L.append(f"| {sp.replace('_', '-')} | {g['songs']} | {c} | {k['tp']} | {k['fp']} | {k['fn']} | "
                         f"{fmt(s['p'])} | {fmt(s['r'])} | **{fmt(s['f'])}** |")
        L.append("")
        L.append("Per finger (the index's onsets: kick or snare; the middle's: toms or cymbals; closer than "
                 "30 ms once), P / R / F:\n")
        L.append("| split | songs | index | middle |")
        L.append("|---|---|---|---|")
        for sp, g in present(a, splits):
            cells = [f"{fmt(g['finger_scores'][k]['p'])} / {fmt(g['finger_scores'][k]['r'])} / "
                     f"**{fmt(g['finger_scores'][k]['f'])}**" for k, _ in FINGERS]
            L.append(f"| {sp.replace('_', '-')} | {g['songs']} | " + " | ".join(cells) + " |")
        L.append("")
        L.append("Per family, P / R / F:\n")
        L.append("| family | songs | " + " | ".join(CLASSES) + " | render s/song |")
        L.append("|---|---|" + "---|" * len(CLASSES) + "---|")
        for fam, g in sorted(a["family"].items(), key=lambda kv: (kv[0] in args.held_out, kv[0])):
            cells = [f"{fmt(g['scores'][c]['p'])} / {fmt(g['scores'][c]['r'])} / {fmt(g['scores'][c]['f'])}" for c in CLASSES]
            tag = " (held out)" if fam in args.held_out else ""
            L.append(f"| {fam}{tag} | {g['songs']} | " + " | ".join(cells) + f" | {g['wall_s'] / g['songs']:.2f} |")
        L.append("")
        for sp, g in present(a, splits):
            L.append(f"Confusion, {sp.replace('_', '-')}: false positives of each detected class by the nearest true "
                     "onset of another class within ±50 ms; misses by the nearest detection of another class.\n")
            L.append("| class | FP | near kick | near snare | near toms | near cymbals | double | nothing || FN | heard as kick | snare | toms | cymbals | silent |")
            L.append("|---|---|---|---|---|---|---|---||---|---|---|---|---|---|")
            for c in CLASSES:
                fp, fn = g["fp_near"][c], g["fn_heard"][c]
                L.append(f"| {c} | {sum(fp.values())} | " + " | ".join(str(fp[o]) if o != c else "·" for o in CLASSES) +
                         f" | {fp['double']} | {fp['nothing']} || {sum(fn.values())} | " +
                         " | ".join(str(fn[o]) if o != c else "·" for o in CLASSES) + f" | {fn['silent']} |")
            L.append("")
            L.append("Recall by hit type: " + ", ".join(
                f"{name} {fmt(g['subtype'][name]['hit'] / g['subtype'][name]['n']) if g['subtype'].get(name, {}).get('n') else '–'}"
                f" ({g['subtype'].get(name, {}).get('n', 0)})" for name, _c, _p in SUBTYPES) + "\n")
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/data/drums")
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "tactus"))
    ap.add_argument("--held-out", default="musescore", help="comma-separated families held out (default musescore)")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=ARGS",
                    help='method name and extra render arguments, e.g. bands="--drums bands"')
    ap.add_argument("--conditions", default="isolated,mix")
    ap.add_argument("--families", default=None, help="only these families (default: all under --data)")
    ap.add_argument("--songs", type=int, default=None, help="at most this many songs per family")
    ap.add_argument("--mix-map", default=None, help="glove map for the mix condition (default: the default map)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "benches", "drums_eval"), help="writes OUT.md and OUT.json")
    args = ap.parse_args()
    args.held_out = [f for f in args.held_out.split(",") if f]
    methods = []
    for m in args.method or ["default="]:
        name, _, margs = m.partition("=")
        methods.append((name, margs))
    conds = [c for c in args.conditions.split(",") if c]
    for c in conds:
        if c not in ("isolated", "mix"):
            sys.exit(f"unknown condition {c!r}")
    if not os.access(args.bin, os.X_OK):
        sys.exit(f"{args.bin} is not an executable (cargo build --release --bin tactus)")
    fams = sorted(d for d in os.listdir(args.data) if os.path.isdir(os.path.join(args.data, d)) and not d.startswith("."))
    if args.families:
        fams = [f for f in fams if f in args.families.split(",")]
    songs = []
    for f in fams:
        ss = sorted(os.path.join(args.data, f, s) for s in os.listdir(os.path.join(args.data, f))
                    if not s.startswith(".") and os.path.exists(os.path.join(args.data, f, s, "truth.json")))
        songs += ss[: args.songs] if args.songs else ss
    if not songs:
        sys.exit(f"no songs under {args.data}")
    jobs = [(s, c, m, a, args.bin, args.mix_map) for m, a in methods for c in conds for s in songs]
    results = []
    t0 = time.time()
    with mp.Pool(args.jobs) as pool:
        for k, r in enumerate(pool.imap_unordered(run_one, jobs)):
            fam = os.path.basename(os.path.dirname(r["song"]))
            r["split"] = "held_out" if fam in args.held_out else "training"
            results.append(r)
            if "error" in r:
                print(f"[{k + 1}/{len(jobs)}] {r['method']} {r['cond']} {r['song']}: FAILED {r['error']}", file=sys.stderr, flush=True)
            elif (k + 1) % 20 == 0 or k + 1 == len(jobs):
                print(f"[{k + 1}/{len(jobs)} {time.time() - t0:.0f}s]", file=sys.stderr, flush=True)
    errors = [r for r in results if "error" in r]
    mismatches = sum(1 for r in results if r.get("mismatch"))
    if mismatches:
        print(f"warning: Python matching differs from tactus eval on {mismatches} runs, e.g. "
              f"{next(r['mismatch'] for r in results if r.get('mismatch'))}", file=sys.stderr)
    agg = aggregate(results)
    md = markdown(agg, args, methods, len(songs), errors, mismatches, songs)
    report = {
        "data": args.data, "held_out": args.held_out, "window_s": WINDOW_S, "methods": dict(methods),
        "conditions": conds, "songs": len(songs), "song_dirs": [os.path.relpath(s, args.data) for s in songs],
        "errors": errors,
        "aggregate": {f"{m}/{c}": a for (m, c), a in agg.items()},
        "per_song": [{k: v for k, v in r.items() if k != "py"} | ({"py_counts": r["py"]["counts"]} if "py" in r else {})
                     for r in sorted(results, key=lambda r: (r["method"], r["cond"], r["song"]))],
    }
    for path, text in ((args.out + ".md", md), (args.out + ".json", json.dumps(report, indent=1) + "\n")):
        tmp = path + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    print(md)
    print(f"wrote {args.out}.md and {args.out}.json ({time.time() - t0:.0f} s)", file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())

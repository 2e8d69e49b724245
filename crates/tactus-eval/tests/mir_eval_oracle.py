#!/usr/bin/env python3
"""mir_eval as the oracle for tactus-eval's melody and onset metrics.

Writes deterministic test inputs to fixtures/mir_eval_cases.json and mir_eval's results to
fixtures/mir_eval_expected.json; the Rust test `mir_eval_oracle` compares tactus-eval with
them (tolerance 1e-6).

    python mir_eval_oracle.py           # (re)generate both files
    python mir_eval_oracle.py --check   # recompute from the committed cases, compare, exit 1 on mismatch

Needs mir_eval and numpy (see requirements-oracle.txt next to this file).
"""
import argparse
import json
import os
import sys

import mir_eval
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = os.path.join(HERE, "fixtures", "mir_eval_cases.json")
EXPECTED = os.path.join(HERE, "fixtures", "mir_eval_expected.json")
TOL = 1e-6


def make_cases():
    rng = np.random.default_rng(20250918)
    melody = []
    # 1: a clean contour with octave errors, small and large detunes, voicing errors
    ref = 220.0 * 2 ** (np.round(rng.uniform(-12, 12, 200)) / 12)
    ref[rng.random(200) < 0.25] = 0.0
    est = ref * 2 ** (rng.normal(0, 30, 200) / 1200)
    est[rng.random(200) < 0.1] *= 2.0
    est[rng.random(200) < 0.05] *= 0.5
    est[rng.random(200) < 0.15] = 0.0
    melody.append({"name": "mixed errors", "ref_hz": ref.tolist(), "est_hz": est.tolist()})
    # 2: negative estimates (pitch guesses on frames the estimator calls unvoiced)
    est2 = ref * 2 ** (rng.normal(0, 20, 200) / 1200)
    flip = rng.random(200) < 0.3
    est2[flip] = -est2[flip]
    melody.append({"name": "negative estimates", "ref_hz": ref.tolist(), "est_hz": est2.tolist()})
    # 3: random frequencies everywhere, heavy false alarms
    ref3 = np.where(rng.random(150) < 0.5, rng.uniform(40, 1000, 150), 0.0)
    est3 = np.where(rng.random(150) < 0.7, rng.uniform(40, 1000, 150), 0.0)
    melody.append({"name": "random", "ref_hz": ref3.tolist(), "est_hz": est3.tolist()})
    # 4: reference all unvoiced (recall is 1 by definition, RPA 0)
    melody.append({"name": "unvoiced reference", "ref_hz": [0.0] * 20, "est_hz": rng.uniform(100, 200, 20).tolist()})
    # 5: chroma fold near multiples of 1200 cents (+-40 cents around 1 and 2 octaves)
    ref5 = rng.uniform(80, 400, 100)
    est5 = ref5 * 2 ** ((1200 * rng.integers(-2, 3, 100) + rng.uniform(-80, 80, 100)) / 1200)
    melody.append({"name": "octave folding", "ref_hz": ref5.tolist(), "est_hz": est5.tolist()})

    onsets = []
    r = np.sort(rng.uniform(0, 10, 40))
    e = np.sort(np.concatenate([r[:32] + rng.normal(0, 0.03, 32), rng.uniform(0, 10, 8)]))
    onsets.append({"name": "jittered", "ref": r.tolist(), "est": e.tolist()})
    # dense clusters where a greedy nearest match is not maximal
    r2 = np.sort(np.concatenate([np.arange(0, 1, 0.04), [2.0, 2.08]]))
    e2 = np.sort(np.concatenate([np.arange(0.02, 1, 0.045), [2.04, 2.12]]))
    onsets.append({"name": "dense", "ref": r2.tolist(), "est": e2.tolist()})
    # window boundaries: offsets of exactly +-0.05 in decimal (floating point decides)
    onsets.append({"name": "boundaries", "ref": [1.0, 2.0, 3.0, 4.1, 5.25], "est": [1.05, 1.95, 3.0500001, 4.05, 5.3]})
    onsets.append({"name": "one empty", "ref": [0.5, 1.5], "est": []})
    r5 = np.sort(rng.uniform(0, 3, 60))
    e5 = np.sort(rng.uniform(0, 3, 70))
    onsets.append({"name": "random dense", "ref": r5.tolist(), "est": e5.tolist()})
    return {"melody": melody, "onsets": onsets}


def compute(cases):
    out = {"melody": [], "onsets": []}
    for c in cases["melody"]:
        ref = np.array(c["ref_hz"], dtype=float)
        est = np.array(c["est_hz"], dtype=float)
        rf, rv = mir_eval.melody.freq_to_voicing(ref)
        ef, ev = mir_eval.melody.freq_to_voicing(est)
        rc = mir_eval.melody.hz2cents(rf)
        ec = mir_eval.melody.hz2cents(ef)
        out["melody"].append({
            "name": c["name"],
            "raw_pitch_accuracy": float(mir_eval.melody.raw_pitch_accuracy(rv, rc, ev, ec)),
            "raw_chroma_accuracy": float(mir_eval.melody.raw_chroma_accuracy(rv, rc, ev, ec)),
            "voicing_recall": float(mir_eval.melody.voicing_recall(rv, ev)),
            "voicing_false_alarm": float(mir_eval.melody.voicing_false_alarm(rv, ev)),
        })
    for c in cases["onsets"]:
        f, p, r = mir_eval.onset.f_measure(np.array(c["ref"], dtype=float), np.array(c["est"], dtype=float), window=0.05)
        out["onsets"].append({"name": c["name"], "f_measure": float(f), "precision": float(p), "recall": float(r)})
    out["mir_eval_version"] = mir_eval.__version__
    return out


def compare(a, b):
    bad = []
    for kind in ("melody", "onsets"):
        for x, y in zip(a[kind], b[kind]):
            for k, v in x.items():
                if k != "name" and abs(v - y[k]) > TOL:
                    bad.append(f"{kind}/{x['name']}/{k}: {v} vs {y[k]}")
        if len(a[kind]) != len(b[kind]):
            bad.append(f"{kind}: case count differs")
    return bad


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", action="store_true", help="recompute from the committed cases and compare")
    args = ap.parse_args()
    if args.check:
        cases = json.load(open(CASES))
        expected = json.load(open(EXPECTED))
        bad = compare(compute(cases), expected)
        for line in bad:
            print("MISMATCH", line)
        print("mir_eval oracle:", "FAIL" if bad else "ok")
        sys.exit(1 if bad else 0)
    cases = make_cases()
    os.makedirs(os.path.dirname(CASES), exist_ok=True)
    with open(CASES, "w") as fh:
        json.dump(cases, fh, indent=1)
        fh.write("\n")
    with open(EXPECTED, "w") as fh:
        json.dump(compute(cases), fh, indent=1)
        fh.write("\n")
    print("wrote", CASES, EXPECTED)


if __name__ == "__main__":
    main()

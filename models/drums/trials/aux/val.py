"""The choice step of RULE_aux.md: F per class on train.py's validation songs (every fourth
song of timgm, csound, sonicpi, synth, remix: 50 songs) for iso, sep and mix, the mean of
the twelve values and of the three snare values, for each model file given. Run from the
repository root:

    corpus/.venv/bin/python models/drums/trials/aux/val.py MODEL.bin...
"""
import os
import sys

sys.path.insert(0, 'models/drums')
import train as T  # noqa: E402

T.HELD_OUT[:] = ['fluid', 'musescore']
items = [it for it in T.songs('/work/data/drums') if it[0] in ('timgm', 'csound', 'sonicpi', 'synth', 'remix')]
tr, va, ho = T.split(items)
# Short-view models (feature set 3, RULE_short.md) need the 1024-point view loaded beside
# the 2048-point one; other models read the first T.BANDS columns.
T.SHORT = any(T.read_model(p) and T.SHORT for p in sys.argv[1:])
D = T.load(va, '/work/data/drums', ['iso', 'sep', 'mix'])
for path in sys.argv[1:]:
    ps, thr = T.read_model(path)
    if not T.SHORT:
        D = [(f, s, c, m[:, :T.BANDS], t) for (f, s, c, m, t) in D]
    allf, snare, rows = [], [], []
    for cond in ('iso', 'sep', 'mix'):
        sel = [(m, t) for (_, _, c, m, t) in D if c == cond]
        res = T.score([T.activations(ps, m) for m, _ in sel], [t for _, t in sel], thr)
        f = [r[2] for r in res]
        allf += f
        snare.append(f[1])
        rows.append(f"{cond} " + " / ".join(f"{x:.4f}" for x in f))
    print(f"{os.path.basename(path)} ({len(sel)} songs): " + "; ".join(rows)
          + f"; mean of 12 {sum(allf) / 12:.4f}; snare mean {sum(snare) / 3:.4f}")

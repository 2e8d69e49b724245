"""Screen: test-time augmentation for the default drum model (validation songs only).
Activations averaged over deterministic retunings / tilts of each window."""
import os, sys, numpy as np
sys.path.insert(0, '/work/main/models/drums'); import train as T
T.HELD_OUT[:] = ['fluid', 'musescore']
data = sys.argv[1] if len(sys.argv) > 1 else '/work/data/drums'
split = sys.argv[2] if len(sys.argv) > 2 else 'val'
fams = ('timgm', 'csound', 'sonicpi', 'synth', 'remix') if split == 'val' else ('fluid', 'musescore')
items = [it for it in T.songs(data) if it[0] in fams]
tr, va, ho = T.split(items)
sel = va if split == 'val' else ho
D = T.load(sel, data, ['iso', 'sep', 'mix'])
ps, thr0 = T.read_model('/work/main/crates/tactus-dsp/weights/drums.bin')
D = [(f, s, c, m[:, :T.BANDS], t) for (f, s, c, m, t) in D]
B = T.BANDS
mc = np.linspace(T._mel(T.F_LO), T._mel(T.F_HI), B + 2)[1:-1]
pos = np.linspace(-1, 1, B, dtype=np.float32)
def variant(x, r, tilt):
    n = x.shape[0]; z = x.reshape(n, -1, B)
    if r != 1.0:
        src = np.interp(T._mel(T._hz(mc) / r), mc, np.arange(B, dtype=np.float64))
        z = T._gather(z, np.repeat(src[None, :], n, 0), 2)
    z = (z + np.float32(tilt) * pos).reshape(n, -1)
    return np.maximum(z - z.max(1, keepdims=True), np.float32(T.FLOOR))
def acts(m, vs):
    x = T.context(m)
    return np.mean([T.sigmoid(T.forward(ps, variant(x, r, t))[-1]) for r, t in vs], axis=0)
SETS = {
 'base': [(1.0, 0.0)],
 'tilt3': [(1.0, 0.0), (1.0, -0.7), (1.0, 0.7)],
 'warp3': [(1.0, 0.0), (1/1.2, 0.0), (1.2, 0.0)],
 'warp3w': [(1.0, 0.0), (1/1.3, 0.0), (1.3, 0.0)],
 'warp3n': [(1.0, 0.0), (1/1.1, 0.0), (1.1, 0.0)],
 'warp5': [(1.0, 0.0), (1/1.3, 0.0), (1/1.15, 0.0), (1.15, 0.0), (1.3, 0.0)],
 'warp2': [(1/1.15, 0.0), (1.15, 0.0)],
 'both5': [(1.0, 0.0), (1.0, -0.7), (1.0, 0.7), (1/1.2, 0.0), (1.2, 0.0)],
}
for name in (sys.argv[3].split(',') if len(sys.argv) > 3 else SETS):
    vs = SETS[name]; allf = []; rows = []
    A = {c: [(acts(m, vs), t) for (_, _, cc, m, t) in D if cc == c] for c in ('iso', 'sep', 'mix')}
    # thresholds re-tuned on the pooled conditions (as train.py does), then scored per condition
    pool = [a for c in A for a in A[c]]
    thr = T.tune([a for a, _ in pool], [t for _, t in pool]) if split == 'val' else None
    for c in A:
        res = T.score([a for a, _ in A[c]], [t for _, t in A[c]], thr)
        f = [r[2] for r in res]; allf += f
        rows.append(f"{c} " + " / ".join(f"{v:.3f}" for v in f) + f" (snare P/R {res[1][0]:.2f}/{res[1][1]:.2f})")
    print(name, 'thr', [round(v, 3) for v in thr], '; '.join(rows), f'mean12 {np.mean(allf):.4f}', flush=True)

import sys, numpy as np
sys.path.insert(0, '/work/main/models/drums'); import train as T, tta
ps, _ = T.read_model('/tmp/s39/drums_committed.bin')
D = tta.validation('/work/data/drums')
B = T.BANDS
def var(x, r, s):
    z = T.retuned(x, r)
    if s != 1.0:
        n = z.shape[0]; win = z.shape[1] // B
        t = np.arange(win, dtype=np.float64)[None, :]
        pos = np.repeat(T.PAST + (t - T.PAST) / s, n, 0)
        z = T._gather(z.reshape(n, win, B), pos, 1).reshape(n, -1)
        z = np.maximum(z - z.max(1, keepdims=True), np.float32(T.FLOOR))
    return z
def acts(m, vs):
    x = T.context(m[:, :B])
    return np.mean([T.sigmoid(T.forward(ps, var(x, r, s))[-1]) for r, s in vs], axis=0)
SETS = {
 'r3': [(1, 1), (1/1.3, 1), (1.3, 1)],
 's3': [(1, 1), (1, 1/1.3), (1, 1.3)],
 'rs5': [(1, 1), (1/1.3, 1), (1.3, 1), (1, 1/1.3), (1, 1.3)],
 'diag3': [(1, 1), (1/1.3, 1/1.2), (1.3, 1.2)],
}
for name in sys.argv[1].split(','):
    A = [acts(m, SETS[name]) for (_, _, _, m, _) in D]; tr = [t for (*_, t) in D]
    thr = T.tune(A, tr); f = []
    for c in T.CONDS:
        sel = [i for i, d in enumerate(D) if d[2] == c]
        f += [r[2] for r in T.score([A[i] for i in sel], [tr[i] for i in sel], thr)]
    print(name, ' '.join(f'{v:.3f}' for v in f), f'mean12 {np.mean(f):.4f}', flush=True)

import sys
import numpy as np
from oofdata import GRID, lg, load  # noqa: F401 (sets the path)
import train as T, fastpick as fast  # noqa: E402
D = load(sys.argv[1:])
c = 1
Y, F = [], []
names = None
for (fam, s, cond), (acts, truth, thr) in sorted(D.items()):
    ref = [h['time_s'] for h in truth['onsets'].get('snare', [])]
    Fs = np.array([T.prf(*fast.counts(acts[:, c], ref, th))[2] for th in GRID])
    ok = np.flatnonzero(Fs >= Fs.max() - 1e-9); best = GRID[ok[len(ok) // 2]]
    Y.append(lg(best) - lg(thr[c]))
    L = lg(acts)
    pk = fast.pick(acts[:, c].astype(np.float64), 0.2)
    P = np.stack([L[i:i + 3].max(0) for i in pk]) if len(pk) else np.zeros((1, 4))
    hi = P[:, c] > lg(thr[c])
    f = dict(
        n_pk=np.log1p(len(pk)), frac_hi=hi.mean(), mean_pk=P[:, c].mean(), std_pk=P[:, c].std(),
        q90=np.percentile(P[:, c], 90), q50=np.percentile(P[:, c], 50),
        cym_at_pk=P[:, 3].mean(), kick_at_pk=P[:, 0].mean(), toms_at_pk=P[:, 2].mean(),
        cym_at_hi=P[hi, 3].mean() if hi.any() else 0, song_cym=L[:, 3].mean(), song_snare=L[:, 1].mean(),
        n_cym=np.log1p(len(fast.pick(acts[:, 3].astype(np.float64), thr[3]))),
        n_sn=np.log1p(len(fast.pick(acts[:, 1].astype(np.float64), thr[1]))),
        iso=float(cond == 'iso'))
    names = list(f); F.append([f[k] for k in names])
Y = np.array(Y); F = np.array(F)
print('y mean %.2f std %.2f' % (Y.mean(), Y.std()))
for k, col in zip(names, F.T):
    print(k.ljust(12), 'corr %.2f' % np.corrcoef(col, Y)[0, 1])

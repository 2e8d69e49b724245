"""Thresholds tuned on out-of-family activations (leave-one-family-out) vs each fold's own."""
import sys, os, numpy as np, pickle
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..', '..'), HERE]
DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')  # fold models and caches (lofo.sh writes them)
import train as T, fastpick as fast
R = [1.0, 1 / 1.3, 1.3]
FAMS = ['sonicpi', 'timgm', 'csound', 'synth', 'remix']
name = sys.argv[1]
pk = f'{DIR}/oofacts_{name}.pkl'
if os.path.exists(pk):
    A = pickle.load(open(pk, 'rb'))
else:
    A = []
    for F in FAMS:
        ps, thr = T.read_model(f'{DIR}/{name}_{F}.bin')
        for (fam, s, cond, m, t) in T.load([it for it in T.songs(os.environ.get('LOFO_DATA', '/work/data/drums')) if it[0] == F], os.environ.get('LOFO_DATA', '/work/data/drums'), ['iso', 'sep']):
            A.append((F, cond, T.activations(ps, m, R), t, thr))
    pickle.dump(A, open(pk, 'wb'))
GRID = np.arange(0.1, 0.951, 0.025)
for c in range(4):
    refs = [[h['time_s'] for h in t['onsets'].get(T.CLASSES[c], [])] for (_, _, _, t, _) in A]
    own = sum(fast.counts(a[:, c], r, thr[c]) for (_, _, a, _, thr), r in zip(A, refs))
    # per-fold offset: tuned on the other four families' OOF songs, applied to the held family
    off = np.zeros(3); offs = []
    for F in FAMS:
        tr = [(x, r) for x, r in zip(A, refs) if x[0] != F]
        te = [(x, r) for x, r in zip(A, refs) if x[0] == F]
        # choose offset d in logit space on tr (each fold model's own threshold + d)
        def lg(p): return np.log(p / (1 - p))
        def sg(z): return 1 / (1 + np.exp(-z))
        best = max(np.arange(-1.5, 1.51, 0.1), key=lambda d: T.prf(*sum(fast.counts(x[2][:, c], r, sg(lg(x[4][c]) + d)) for x, r in tr))[2])
        offs.append(best)
        off += sum(fast.counts(x[2][:, c], r, sg(lg(x[4][c]) + best)) for x, r in te)
    print(T.CLASSES[c], 'own thresholds F %.3f (P %.3f R %.3f)' % (T.prf(*own)[2], *T.prf(*own)[:2]),
          ' OOF-tuned offset F %.3f (P %.3f R %.3f)' % (T.prf(*off)[2], *T.prf(*off)[:2]), 'offsets', ' '.join('%.1f' % o for o in offs))

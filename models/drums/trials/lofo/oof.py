"""Out-of-fold activations: each training family scored by the fold model that never saw it."""
import sys, os, numpy as np, pickle
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..', '..'), HERE]
DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')  # fold models and caches (lofo.sh writes them)
import train as T
data = os.environ.get('LOFO_DATA', '/work/data/drums')
R = [1.0, 1 / 1.3, 1.3]
out = {}
for F in sys.argv[1:]:
    ps, thr = T.read_model(f'{DIR}/fold_{F}.bin')
    items = [it for it in T.songs(data) if it[0] == F]
    rows = T.load(items, data, ['iso', 'sep'])
    for (fam, s, c, m, t) in rows:
        out[(fam, s, c)] = (T.activations(ps, m, R).astype(np.float32), t, thr)
    print(F, len(rows), 'thr', thr, flush=True)
    pickle.dump(out, open(f'{DIR}/oof_{"_".join(sys.argv[1:])}.pkl', 'wb'))

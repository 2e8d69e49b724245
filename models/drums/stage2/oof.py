"""Out-of-fold activations: each training family scored by the fold model that never saw it."""
import sys, os, numpy as np, pickle
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..'), HERE]
DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')  # fold models and caches (lofo.sh writes them)
import train as T
data = os.environ.get('LOFO_DATA', '/work/data/drums')
R = [1.0, 1 / 1.3, 1.3]
NAME = os.environ.get('OOF_NAME', 'fold')  # the fold models' name (lofo.sh NAME)
CONDS = os.environ.get('OOF_CONDS', 'iso,sep').split(',')
out = {}
for F in sys.argv[1:]:
    ps, thr = T.read_model(f'{DIR}/{NAME}_{F}.bin')
    items = [it for it in T.songs(data) if it[0] == F]
    rows = T.load(items, data, CONDS)
    for (fam, s, c, m, t) in rows:
        out[(fam, s, c)] = (T.activations(ps, m, R).astype(np.float32), t, thr)
    print(F, len(rows), 'thr', thr, flush=True)
    tag = '' if NAME == 'fold' else NAME + '_'
    pickle.dump(out, open(f'{DIR}/oof_{tag}{"_".join(sys.argv[1:])}.pkl', 'wb'))

"""Pooled out-of-family F of a set of fold models: python lofo_eval.py NAME [NAME2 ...]"""
import sys, os, numpy as np
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..', '..'), HERE]
DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')  # fold models and caches (lofo.sh writes them)
import train as T, fastpick as fast
R = [1.0, 1 / 1.3, 1.3]
FAMS = ['sonicpi', 'timgm', 'csound', 'synth', 'remix']
cache = {}
for name in sys.argv[1:]:
    tot = {}
    for F in FAMS:
        path = f'{DIR}/{name}_{F}.bin'
        if not os.path.exists(path):
            continue
        ps, thr = T.read_model(path)
        if F not in cache:
            cache[F] = T.load([it for it in T.songs(os.environ.get('LOFO_DATA', '/work/data/drums')) if it[0] == F], os.environ.get('LOFO_DATA', '/work/data/drums'), ['iso', 'sep'])
        for (fam, s, cond, m, t) in cache[F]:
            a = T.activations(ps, m, R)
            for c in range(4):
                ref = [h['time_s'] for h in t['onsets'].get(T.CLASSES[c], [])]
                k = (cond, c)
                tot[k] = tot.get(k, 0) + fast.counts(a[:, c], ref, thr[c])
                k = (cond, c, F)
                tot[k] = tot.get(k, 0) + fast.counts(a[:, c], ref, thr[c])
    fs = {k: T.prf(*v)[2] for k, v in tot.items()}
    line = ' | '.join('%s %s' % (cond, ' '.join('%.3f' % fs[(cond, c)] for c in range(4))) for cond in ['iso', 'sep'])
    print(name.ljust(10), line, ' mean8 %.4f' % np.mean([fs[(cd, c)] for cd in ['iso', 'sep'] for c in range(4)]))
    for F in FAMS:
        if ('iso', 0, F) in fs:
            print('   ', F.ljust(8), ' '.join('%.3f' % fs[(cd, c, F)] for cd in ['iso', 'sep'] for c in range(4)))

"""The choice step of RULE_live_mixcond.md: F per class and their mean on the `mix` condition
of train.py's validation songs (every fourth song of timgm, csound, sonicpi, synth), for
each model file given. Run from the repository root:

    corpus/.venv/bin/python models/drums/trials/live_mixcond/valmix.py MODEL.bin...
"""
import sys, os
sys.path.insert(0, 'models/drums')
import train as T
T.HELD_OUT[:] = ['fluid', 'musescore']
items = [it for it in T.songs('/work/data/drums') if it[0] in ('timgm', 'csound', 'sonicpi', 'synth')]
tr, va, ho = T.split(items)
D = T.load(va, '/work/data/drums', ['mix'])
for path in sys.argv[1:]:
    ps, thr = T.read_model(path)
    acts = [T.activations(ps, m) for (_, _, _, m, _) in D]
    res = T.score(acts, [t for *_, t in D], thr)
    f = [r[2] for r in res]
    print(os.path.basename(path), ' '.join(f'{x:.4f}' for x in f), f'mean {sum(f)/4:.4f}')

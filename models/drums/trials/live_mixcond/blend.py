"""Replays the default model on the separated drum stem blended with the live model on the raw
mix (model card, "The raw-mix live model as a second view"): F per class on the training
families' validation songs. From the repository root:

    corpus/.venv/bin/python models/drums/trials/live_mixcond/blend.py timgm,csound,sonicpi,synth,remix
"""
import sys
sys.path.insert(0, 'models/drums')
import numpy as np
import train as T
T.HELD_OUT[:] = ['fluid', 'musescore']
fams = sys.argv[1].split(',')
data = sys.argv[2] if len(sys.argv) > 2 else '/work/data/drums'
items = [it for it in T.songs(data) if it[0] in fams]
tr, va, ho = T.split(items)
sel = va if sys.argv[3:4] != ['held'] else ho
D = T.load(sel, data, ['sep', 'mix'])
by = {}
for fam, s, c, m, t in D:
    by.setdefault((fam, s), {})[c] = (m, t)
pd, td = T.read_model('crates/tactus-dsp/weights/drums.bin')
a_sep, a_mix, truths = [], [], []
for k, v in by.items():
    T.PAST, T.FUTURE = 7, 4
    a_sep.append(T.activations(pd, v['sep'][0]))
    truths.append(v['sep'][1])
pl, tl = T.read_model('crates/tactus-dsp/weights/drums_live.bin')
for k, v in by.items():
    a_mix.append(T.activations(pl, v['mix'][0]))
def rep(acts, thr, name):
    r = T.score(acts, truths, thr)
    f = [x[2] for x in r]
    print(f"{name:28s}", ' '.join(f"{x:.3f}" for x in f), f"mean {np.mean(f):.4f}")
rep(a_sep, td, 'default on sep')
rep(a_mix, tl, 'live on mix')
for w in (0.15, 0.25, 0.35, 0.5):
    acts = [(1 - w) * a + w * b[:len(a)] if len(b) >= len(a) else (1 - w) * a[:len(b)] + w * b for a, b in zip(a_sep, a_mix)]
    rep(acts, td, f'blend w={w} (default thr)')
    thr = [(1 - w) * x + w * y for x, y in zip(td, tl)]
    rep(acts, thr, f'blend w={w} (mixed thr)')

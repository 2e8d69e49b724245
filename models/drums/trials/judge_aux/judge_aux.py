"""Issue 10 trial (rule trials/RULE_judge_aux.md): the snare's judge learnt with the trial
corpus families' songs (`choke`, `choke2`) beside the training families', the network as it is.

Each trial song is made of one training source's sounds (its name starts with the source), so
it is scored by the fold model that never heard that source (lofo.sh fold), and in the
leave-one-family-out screen it is left out with its source and never scored itself.

  judge_aux.py oof FAMILY...                          -> $LOFO_DIR/oof_aux_<FAMILY_...>.pkl
  judge_aux.py lofo K LOW BASE.pkl [AUX.pkl...]       snare F through the judge, out of family
  judge_aux.py save K LOW OUT.json BASE.pkl [AUX.pkl...]   the judge learnt on everything

JUDGE_SPEC=1 (rule trials/RULE_judge_spec.md): three more features per candidate, the rise of
its log-mel spectrum (max of hops i..i+2 less the mean of hops i-3..i-1, clipped at 0) averaged
over the bands centred in 100-300 Hz, 300-2000 Hz and 5-16 kHz, over 10.

STAGE2_BAG=B (rule trials/RULE_judge_bag.md): B perceptrons (seeds 0..B-1) on the same rows,
merged into one of B x STAGE2_HIDDEN units (output weights over B, output bias the mean).
"""
import json
import os
import pickle
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
LOFO = os.path.join(HERE, '..', 'lofo')
sys.path[:0] = [os.path.join(HERE, '..', '..'), LOFO]
import fastpick as fast  # noqa: E402
import stage2 as S  # noqa: E402
import train as T  # noqa: E402

DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')
DATA = os.environ.get('LOFO_DATA', '/work/data/drums')
R = [1.0, 1 / 1.3, 1.3]
SNARE = T.CLASSES.index('snare')
SPEC = os.environ.get('JUDGE_SPEC', '') == '1'


BAG = int(os.environ.get('STAGE2_BAG', '0'))


def train_judge(rows):
    """stage2.py's judge and cut, or with BAG the merged bag and its cut."""
    if not BAG:
        return S.train_class(rows)
    X = np.concatenate([r['X'] for r in rows])
    y = np.concatenate([r['y'] for r in rows])
    bag = []
    for seed in range(BAG):
        S.MLP_SEED = seed
        bag.append(S.fit_mlp(X, y, S.HIDDEN))
    S.MLP_SEED = 0
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)  # noqa: E731
    judge = {'hidden': np.concatenate([j['hidden'] for j in bag]),
             'out': f32(np.concatenate([j['out'] for j in bag]) / BAG),
             'out_bias': float(f32(np.mean([j['out_bias'] for j in bag])))}
    cut = max(S.CUTS, key=lambda t: T.prf(*S.counts(rows, judge, t))[2])
    return judge, float(cut)


def centres():
    """The drum front end's 48 band centres in Hz (HTK mel, 20 Hz to 16 kHz)."""
    mel = lambda f: 2595.0 * np.log10(1 + f / 700.0)  # noqa: E731
    m = np.linspace(mel(20.0), mel(16000.0), T.BANDS + 2)[1:-1]
    return 700.0 * (10 ** (m / 2595.0) - 1)


GROUPS = [(c >= lo) & (c < hi) for c in [centres()] for lo, hi in ((100, 300), (300, 2000), (5000, 16001))]


def spectral(mel, hops):
    """(n, 3): the candidates' rise per band group, over 10."""
    n = len(mel)
    out = np.zeros((len(hops), 3))
    for j, i in enumerate(hops):
        now = mel[i:min(i + 3, n), :T.BANDS].max(0)
        before = mel[max(i - 3, 0):i, :T.BANDS].mean(0) if i > 0 else np.full(T.BANDS, T.LOG_FLOOR)
        r = np.maximum(now - before, 0.0)
        out[j] = [r[g].mean() / 10.0 for g in GROUPS]
    return out


def source(song):
    return song.split('-', 1)[0]


def oof(fams):
    out = {}
    for F in ('sonicpi', 'timgm', 'csound'):
        items = [it for it in T.songs(DATA) if it[0] in fams and source(it[1]) == F]
        if not items:
            continue
        ps, thr = T.read_model(f'{DIR}/fold_{F}.bin')
        for (fam, s, c, m, t) in T.load(items, DATA, ['iso', 'sep']):
            out[(fam, s, c)] = (T.activations(ps, m, R).astype(np.float32), t, thr)
        print(F, len(items), 'songs', flush=True)
    path = f'{DIR}/oof_aux_{"_".join(fams)}.pkl'
    pickle.dump(out, open(path, 'wb'))
    print('wrote', path)


def rows_of(path, k, low, aux):
    """stage2.py's snare rows; a trial song's family is its source, marked aux."""
    rows = []
    for (fam, s, cond), (acts, truth, thr) in sorted(pickle.load(open(path, 'rb')).items()):
        ref = [h['time_s'] for h in truth['onsets'].get('snare', [])]
        hops, X, y = S.cands(acts, SNARE, ref, k, low)
        if SPEC:
            mel = T.features(os.path.join(DATA, fam, s), cond, os.path.join(DATA, ".features", fam, f"{s}.{cond}.f32"))
            X = np.concatenate([X, spectral(mel, hops)], axis=1)
        rows.append(dict(fam=source(s) if aux else fam, aux=aux, cond=cond, c=SNARE,
                         a=acts[:, SNARE], ref=ref, g=thr[SNARE], hops=hops, X=X, y=y))
    return rows


def load(k, low, base, auxes):
    rows = rows_of(base, k, low, False)
    for p in auxes:
        rows += rows_of(p, k, low, True)
    return rows


def lofo(k, low, base, auxes):
    rows = load(k, low, base, auxes)
    fams = sorted({r['fam'] for r in rows if not r['aux']})
    G, A = {}, {}
    for F in fams:
        judge, cut = train_judge([r for r in rows if r['fam'] != F])
        for r in rows:
            if r['fam'] == F and not r['aux']:
                for key in (F, 'all', r['cond']):
                    G[key] = G.get(key, 0) + fast.counts(r['a'], r['ref'], r['g'])
                    A[key] = A.get(key, 0) + S.counts([r], judge, cut)
    n_aux = sum(r['aux'] for r in rows) // 2
    print('K %d LOW %g aux songs %d: snare %.3f->%.3f (iso %.3f->%.3f, sep %.3f->%.3f) [%s]' % (
        k, low, n_aux, T.prf(*G['all'])[2], T.prf(*A['all'])[2], T.prf(*G['iso'])[2],
        T.prf(*A['iso'])[2], T.prf(*G['sep'])[2], T.prf(*A['sep'])[2],
        ' '.join('%s %+.3f' % (F[:5], T.prf(*A[F])[2] - T.prf(*G[F])[2]) for F in fams)), flush=True)


def save(k, low, path, base, auxes):
    rows = load(k, low, base, auxes)
    judge, cut = train_judge(rows)
    res = {'k': k, 'low': low, 'shrink': S.SHRINK,
           'classes': {'snare': {**{key: np.asarray(v).tolist() for key, v in judge.items()}, 'cut': cut}}}
    with open(path, 'w') as f:
        json.dump(res, f, indent=1)
    print('wrote', path)


if __name__ == '__main__':
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == 'oof':
        oof(args)
    elif cmd == 'lofo':
        lofo(int(args[0]), float(args[1]), args[2], args[3:])
    elif cmd == 'save':
        save(int(args[0]), float(args[1]), args[2], args[3], args[4:])
    else:
        sys.exit(__doc__)

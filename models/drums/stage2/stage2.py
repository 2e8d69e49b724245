"""A second stage for the drum transcriber's onsets, learnt out of family (issue 10 trial).

The network's activations are biased differently on every kit it has not heard; thresholds
tuned on its own training kits do not know how. This stage is trained on *out-of-family*
activations (oof.py: each training family scored by the fold model that never saw it), so it
learns how the network's outputs behave on an unheard kit.

Per class c: candidates are the peak picker's onsets at a low threshold LOW. Each candidate
waits K hops; its features are the logits of the four classes' largest activation over the
hops i..i+K, a bias, and the same four logits minus the running mean of the song's earlier
candidates of class c, times m / (m + SHRINK) (m: how many), plus that factor. A logistic
regression scores it; it is an onset where the score reaches the class's cut. Causal: the
decision is made at hop i + K (K hops of added latency); only earlier candidates inform it.

  stage2.py lofo  K LOW PICKLES...          leave-one-family-out F against each fold's own thresholds
  stage2.py save  K LOW OUT.json PICKLES... weights fitted on every family (the candidate)
  stage2.py write STAGE2.json INNER.bin OUT.bin [snare]   the staged model file
      ("TACTUSD2", read by tactus_dsp::drums) around INNER with the named classes' judges
  stage2.py replay MODEL STAGE2.json DATA [iso,sep] [snare]   held-out replay: committed vs
      stage 2 on the named classes (the others keep the model's picker)
"""
import json
import os
import pickle
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..'), HERE]
import fastpick as fast  # noqa: E402
import train as T  # noqa: E402
from oofdata import lg  # noqa: E402

SHRINK = 8.0
L2 = 1e-2
CUTS = np.arange(-3, 3.01, 0.25)
# The judge: HIDDEN = 0, the logistic regression (the stage of 2026-11-28 21:00); HIDDEN > 0,
# a perceptron with that many ReLU units on the same features (trained by Adam, MLP_* below;
# screened 2026-11-29, models/drums/README.md).
HIDDEN = int(os.environ.get('STAGE2_HIDDEN', '0'))
MLP_EPOCHS, MLP_BATCH, MLP_LR, MLP_L2, MLP_SEED = 30, 256, 1e-3, 1e-4, 0


# Screen (2026-11-29): song-adaptive templates. TEMPL = '' (the committed stage), 'rise' or
# 'shape': each candidate's spectrum is compared with the running means of the song's earlier
# confident snares and confident cymbals (cosine), two more features.
TEMPL = os.environ.get('STAGE2_TEMPL', '')
CLASSES_ONLY = [c for c in os.environ.get('STAGE2_CLASSES', '').split(',') if c]  # screen: these classes only
CONF = 0.85  # a confident detection: picked at this threshold


def descriptor(mel, i):
    """The candidate's spectrum: 'rise', the largest log-mel level of hops i..i+2 above the mean
    of hops i-3..i-1 (clipped at 0); 'shape', hop i+1's log-mel frame less its band mean."""
    n = len(mel)
    if TEMPL == 'rise':
        now = mel[i:min(i + 3, n), :T.BANDS].max(0)
        before = mel[max(i - 3, 0):i, :T.BANDS].mean(0) if i > 0 else np.full(T.BANDS, T.LOG_FLOOR)
        d = np.maximum(now - before, 0.0)
    else:
        f = mel[min(i + 1, n - 1), :T.BANDS].astype(np.float64)
        d = f - f.mean()
    nrm = np.linalg.norm(d)
    return d / nrm if nrm > 0 else d


def template_feats(acts, mel, hops, c):
    """(n, 2): shrunk cosines of each candidate with the song's earlier confident snares (snare
    picked at CONF, cymbals below 0.5) and confident cymbals (snare below 0.15)."""
    sn = [h for h in fast.pick(acts[:, 1].astype(np.float64), CONF) if acts[h, 3] < 0.5]
    cy = [h for h in fast.pick(acts[:, 3].astype(np.float64), CONF) if acts[h:h + 2, 1].max() < 0.15]
    out = np.zeros((len(hops), 2))
    for col, conf in enumerate((sn, cy)):
        s = np.zeros(T.BANDS)
        m = 0
        q = 0
        for j, i in enumerate(hops):
            while q < len(conf) and conf[q] < i:
                s += descriptor(mel, conf[q])
                m += 1
                q += 1
            if m:
                nrm = np.linalg.norm(s)
                cos = float(descriptor(mel, i) @ s / nrm) if nrm > 0 else 0.0
                out[j, col] = m / (m + SHRINK) * cos
    return out


def cands(acts, c, ref, k, low, mel=None):
    """Candidate hops of class c, their features (n, 10, or 12 with templates) and labels
    (greedy match, 50 ms)."""
    a = acts[:, c].astype(np.float64)
    hops = fast.pick(a, low)
    n = len(acts)
    L = (lg(np.stack([acts[i:min(i + k + 1, n)].max(0) for i in hops]))
         if len(hops) else np.zeros((0, 4)))
    X = np.zeros((len(hops), 10))
    s = np.zeros(4)
    for j in range(len(hops)):
        mean = s / j if j else np.zeros(4)
        sh = j / (j + SHRINK)
        X[j] = [*L[j], 1.0, *(sh * (L[j] - mean)), sh]
        s += L[j]
    if TEMPL == 'quad':  # screen: pairwise products of the logits and of their offsets
        iu = np.triu_indices(4)
        Q = np.stack([np.outer(x[:4], x[:4])[iu] for x in X]) if len(X) else np.zeros((0, 10))
        O = np.stack([np.outer(x[5:9], x[5:9])[iu] for x in X]) if len(X) else np.zeros((0, 10))
        X = np.concatenate([X, Q / 10, O / 10], axis=1)
    elif TEMPL == 'ctx':  # screen: the logits of hops i-2 and i+1 apart from the peak
        n = len(acts)
        A = np.stack([np.concatenate([lg(acts[max(i - 2, 0)]), lg(acts[min(i + 1, n - 1)])]) for i in hops]) \
            if len(hops) else np.zeros((0, 8))
        X = np.concatenate([X, A], axis=1)
    elif TEMPL and mel is not None:
        X = np.concatenate([X, template_feats(acts, mel, hops, c)], axis=1)
    y = np.zeros(len(hops))
    ref = np.sort(np.asarray(ref, np.float64))
    used = np.zeros(len(ref), bool)
    for j, i in enumerate(hops):
        hit = np.flatnonzero((np.abs(ref - i * T.HOP_S) <= T.WINDOW_S) & ~used)
        if len(hit):
            used[hit[0]] = True
            y[j] = 1
    return hops, X, y


def fit(X, y):
    """L2-regularised logistic regression by Newton's method."""
    w = np.zeros(X.shape[1])
    for _ in range(50):
        p = 1 / (1 + np.exp(-X @ w))
        g = X.T @ (p - y) + L2 * w
        H = (X * (p * (1 - p))[:, None]).T @ X + L2 * np.eye(len(w))
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-10:
            break
    return w


def fit_mlp(X, y, hidden):
    """A perceptron X -> hidden ReLU units -> one logit, cross-entropy, Adam; the inputs'
    standardisation is folded into the first layer (constant columns are left as they are).
    Returns the judge {'hidden': (hidden, d + 1) rows of weights then bias, 'out': (hidden,),
    'out_bias'}, rounded to f32 as the staged file stores it."""
    rng = np.random.default_rng(MLP_SEED)
    sd = X.std(0)
    const = sd < 1e-3
    mu = np.where(const, 0.0, X.mean(0))
    sd = np.where(const, 1.0, sd)
    Xs = (X - mu) / sd
    d = X.shape[1]
    ps = [rng.normal(0, np.sqrt(2 / d), (d, hidden)), np.zeros(hidden),
          rng.normal(0, np.sqrt(1 / hidden), hidden), np.zeros(1)]
    m1 = [np.zeros_like(p) for p in ps]
    m2 = [np.zeros_like(p) for p in ps]
    t = 0
    for _ in range(MLP_EPOCHS):
        perm = rng.permutation(len(Xs))
        for k in range(0, len(perm), MLP_BATCH):
            b = perm[k:k + MLP_BATCH]
            x = Xs[b]
            h = np.maximum(x @ ps[0] + ps[1], 0)
            p = 1 / (1 + np.exp(-(h @ ps[2] + ps[3][0])))
            g = (p - y[b]) / len(b)
            gh = np.outer(g, ps[2]) * (h > 0)
            grads = [x.T @ gh + MLP_L2 * ps[0], gh.sum(0), h.T @ g + MLP_L2 * ps[2], np.array([g.sum()])]
            t += 1
            for j in range(4):
                m1[j] = 0.9 * m1[j] + 0.1 * grads[j]
                m2[j] = 0.999 * m2[j] + 0.001 * grads[j] ** 2
                ps[j] -= MLP_LR * (m1[j] / (1 - 0.9 ** t)) / (np.sqrt(m2[j] / (1 - 0.999 ** t)) + 1e-8)
    W1 = ps[0] / sd[:, None]
    b1 = ps[1] - (mu / sd) @ ps[0]
    f32 = lambda a: np.asarray(a, np.float32).astype(np.float64)  # noqa: E731
    return {'hidden': f32(np.concatenate([W1.T, b1[:, None]], axis=1)), 'out': f32(ps[2]),
            'out_bias': float(f32(ps[3][0]))}


def score(judge, X):
    """The judge's score of each candidate (rows of X): w . x, or the perceptron's logit."""
    if len(X) == 0:
        return np.zeros(0)
    if 'hidden' not in judge:
        return X @ np.asarray(judge['w'])
    H = np.asarray(judge['hidden'])
    h = np.maximum(X @ H[:, :-1].T + H[:, -1], 0)
    return h @ np.asarray(judge['out']) + judge['out_bias']


def counts(rows, judge, cut):
    C = np.zeros(3)
    for r in rows:
        keep = r['hops'][score(judge, r['X']) >= cut] if len(r['hops']) else r['hops']
        C += fast.match(keep * T.HOP_S, np.sort(np.asarray(r['ref'], np.float64)))
    return C


def train_class(rows):
    X = np.concatenate([r['X'] for r in rows])
    y = np.concatenate([r['y'] for r in rows])
    judge = fit_mlp(X, y, HIDDEN) if HIDDEN else {'w': fit(X, y)}
    cut = max(CUTS, key=lambda t: T.prf(*counts(rows, judge, t))[2])
    return judge, float(cut)


def load_rows(pickles, k, low):
    D = {}
    for f in pickles:
        D.update(pickle.load(open(f, 'rb')))
    rows = []
    M = {}
    if TEMPL in ('rise', 'shape'):  # the log-mel frames the fold models read (train.py's feature cache)
        data = os.environ.get('LOFO_DATA', '/work/data/drums')
        for (fam, s, cond) in D:
            M[(fam, s, cond)] = T.features(os.path.join(data, fam, s), cond,
                                           os.path.join(data, ".features", fam, f"{s}.{cond}.f32"))
    for (fam, s, cond), (acts, truth, thr) in sorted(D.items()):
        for c in range(4):
            if CLASSES_ONLY and T.CLASSES[c] not in CLASSES_ONLY:
                continue
            ref = [h['time_s'] for h in truth['onsets'].get(T.CLASSES[c], [])]
            hops, X, y = cands(acts, c, ref, k, low, M.get((fam, s, cond)))
            rows.append(dict(fam=fam, cond=cond, c=c, a=acts[:, c], ref=ref, g=thr[c],
                             hops=hops, X=X, y=y))
    return rows


def judged_out_of_family(rows, c):
    """Each class-c row's (TP, FP, FN) through a judge learnt on the other families' rows."""
    out = {}
    for F in sorted({r['fam'] for r in rows}):
        judge, cut = train_class([r for r in rows if r['c'] == c and r['fam'] != F])
        for r in rows:
            if r['c'] == c and r['fam'] == F:
                out[id(r)] = counts([r], judge, cut)
    return out


def lofo(k, low, pickles):
    rows = load_rows(pickles, k, low)
    fams = sorted({r['fam'] for r in rows})
    out = []
    for c in sorted({r['c'] for r in rows}):
        G, A = {}, {}
        judged = judged_out_of_family(rows, c)
        for r in rows:
            if r['c'] == c:
                for key in (r['fam'], 'all'):
                    G[key] = G.get(key, 0) + fast.counts(r['a'], r['ref'], r['g'])
                    A[key] = A.get(key, 0) + judged[id(r)]
        out.append('%s %.3f->%.3f [%s]' % (T.CLASSES[c], T.prf(*G['all'])[2], T.prf(*A['all'])[2],
                   ' '.join('%s %+.3f' % (F[:5], T.prf(*A[F])[2] - T.prf(*G[F])[2]) for F in fams)))
    print('K', k, 'LOW', low, '\n  ' + '\n  '.join(out), flush=True)


def save(k, low, path, pickles):
    rows = load_rows(pickles, k, low)
    res = {'k': k, 'low': low, 'shrink': SHRINK, 'classes': {}}
    for c in sorted({r['c'] for r in rows}):
        judge, cut = train_class([r for r in rows if r['c'] == c])
        res['classes'][T.CLASSES[c]] = {**{key: np.asarray(v).tolist() for key, v in judge.items()}, 'cut': cut}
    with open(path, 'w') as f:
        json.dump(res, f, indent=1)
    print('wrote', path)


def write(stage, inner, out, classes):
    """The staged file: "TACTUSD2", u32 version, wait; f32 low, shrink; u32 class mask; per
    judged class (class order) its judge; u32 length and the inner file. Version 1 (every
    judge linear): f32 w[10], cut. Version 2: u32 hidden units H, then for H = 0 f32 w[10],
    cut, else f32 per unit w[10] and bias (H x 11), f32 out[H], out_bias, cut."""
    import struct
    st = json.load(open(stage))
    mask = sum(1 << T.CLASSES.index(c) for c in classes)
    judged = [st['classes'][name] for name in T.CLASSES if name in classes]
    version = 2 if any('hidden' in cw for cw in judged) else 1
    buf = bytearray(b"TACTUSD2")
    buf += struct.pack("<2I2fI", version, st['k'], st['low'], st['shrink'], mask)
    for cw in judged:
        if version == 1:
            buf += struct.pack("<11f", *cw['w'], cw['cut'])
        elif 'hidden' not in cw:
            buf += struct.pack("<I11f", 0, *cw['w'], cw['cut'])
        else:
            H = np.asarray(cw['hidden'], np.float32)
            assert H.shape[1] == 11
            buf += struct.pack("<I", len(H)) + H.astype("<f4").tobytes()
            buf += np.asarray(cw['out'], "<f4").tobytes() + struct.pack("<2f", cw['out_bias'], cw['cut'])
    body = open(inner, 'rb').read()
    buf += struct.pack("<I", len(body)) + body
    tmp = out + '.tmp'
    with open(tmp, 'wb') as f:
        f.write(buf)
    os.replace(tmp, out)
    print('wrote', out, len(buf), 'bytes')


def replay(model, stage, data, conds, classes):
    """Held-out replay: the model's own thresholds against stage 2, train.py's scorer."""
    ps, thr = T.read_model(model)
    st = json.load(open(stage))
    k, low = st['k'], st['low']
    items = [it for it in T.songs(data) if it[0] in ('fluid', 'musescore')]
    rows = T.load(items, data, conds)
    res = {}
    for (fam, s, cond, m, truth) in rows:
        acts = T.activations(ps, m)
        for c, name in enumerate(T.CLASSES):
            ref = [h['time_s'] for h in truth['onsets'].get(name, [])]
            cw = st['classes'].get(name) if name in classes else None
            base = fast.counts(acts[:, c], ref, thr[c])
            if cw is None:
                new = base
            else:
                hops, X, _ = cands(acts, c, ref, k, low)
                new = counts([{'hops': hops, 'X': X, 'ref': ref}], cw, cw['cut'])
            for key in ((cond, c), (cond, c, fam)):
                b, n = res.get(key, (0, 0))
                res[key] = (b + base, n + new)
    fs = []
    for cond in conds:
        line = []
        for c, name in enumerate(T.CLASSES):
            b, n = res[(cond, c)]
            fb, fn_ = T.prf(*b)[2], T.prf(*n)[2]
            fs.append((fb, fn_))
            pb, pn = T.prf(*b)[0], T.prf(*n)[0]
            line.append('%s %.3f -> %.3f (P %.3f -> %.3f)' % (name, fb, fn_, pb, pn))
        print(cond, ' | '.join(line))
    print('mean of %d: %.4f -> %.4f' % (len(fs), np.mean([a for a, _ in fs]), np.mean([b for _, b in fs])))


if __name__ == '__main__':
    cmd = sys.argv[1]
    if cmd == 'lofo':
        lofo(int(sys.argv[2]), float(sys.argv[3]), sys.argv[4:])
    elif cmd == 'save':
        save(int(sys.argv[2]), float(sys.argv[3]), sys.argv[4], sys.argv[5:])
    elif cmd == 'write':
        write(sys.argv[2], sys.argv[3], sys.argv[4], (sys.argv[5] if len(sys.argv) > 5 else 'snare').split(','))
    elif cmd == 'replay':
        replay(sys.argv[2], sys.argv[3], sys.argv[4], (sys.argv[5] if len(sys.argv) > 5 else 'iso,sep').split(','),
               (sys.argv[6] if len(sys.argv) > 6 else 'snare').split(','))
    else:
        sys.exit(__doc__)

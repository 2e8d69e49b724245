import json, os, subprocess, sys, tempfile, numpy as np, wave
sys.path[:0] = ['models/drums/trials/lofo', 'models/drums']
import stage2 as S, train as T
ps, thr = T.read_model('crates/tactus-dsp/weights/drums.bin')
st = json.load(open('models/drums/trials/stage2/stage2_k1.json'))
cw = st['classes']['snare']
def read(p):
    import soundfile as sf
    x, sr = sf.read(p, dtype='float32', always_2d=True)
    return x.mean(1), sr
rows = []
for song in sys.argv[1:]:
    fam, name = song.rstrip('/').split('/')[-2:]
    mel = T.features(song, 'iso', f'/tmp/gatecheck/{fam}/{name}.iso.f32')
    acts = T.activations(ps, mel)
    hops, X, _ = S.cands(acts, 1, [], st['k'], st['low'])
    want = hops[(X @ np.asarray(cw['w'])) >= cw['cut']]
    x, sr = read(song + '/drums.wav')
    hop = 441
    n = len(x) // hop + 1
    pad = np.concatenate([np.zeros(hop), x, np.zeros(3 * hop)])
    rms = np.array([10 * np.log10(np.mean(pad[i * hop:i * hop + 2 * hop] ** 2) + 1e-20) for i in range(n)])
    ref = rms.max()
    truth = np.array([h['time_s'] for h in json.load(open(song + '/truth.json'))['onsets']['snare']])
    for i in want:
        true = len(truth) and np.min(np.abs(truth - i * 0.01)) <= 0.05
        r0 = rms[i] - ref
        r2 = rms[i:i + 3].max() - ref
        rows.append((true, r0, r2))
rows = np.array(rows, dtype=float)
for lab, sel in (('true', rows[:, 0] == 1), ('false', rows[:, 0] == 0)):
    r = rows[sel]
    print(lab, len(r), 'closed by 35 dB at hop i:', int((r[:, 1] < -35).sum()), ' with max over i..i+2:', int((r[:, 2] < -35).sum()),
          ' at 45 dB:', int((r[:, 1] < -45).sum()))

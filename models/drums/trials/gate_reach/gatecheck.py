import json, os, subprocess, sys, tempfile, numpy as np
sys.path[:0] = ['models/drums/trials/lofo', 'models/drums']
import stage2 as S, train as T
ps, thr = T.read_model('crates/tactus-dsp/weights/drums.bin')
st = json.load(open('models/drums/trials/stage2/stage2_k1.json'))
cw = st['classes']['snare']
tot = dict(gated=0, gated_true=0, kept=0, kept_true=0)
for song in sys.argv[1:]:
    fam, name = song.rstrip('/').split('/')[-2:]
    mel = T.features(song, 'iso', f'/tmp/gatecheck/{fam}/{name}.iso.f32')
    acts = T.activations(ps, mel)
    hops, X, _ = S.cands(acts, 1, [], st['k'], st['low'])
    want = hops[(X @ np.asarray(cw['w'])) >= cw['cut']] * 0.01
    truth = json.load(open(song + '/truth.json'))
    ref = np.array([h['time_s'] for h in truth['onsets']['snare']])
    d = tempfile.mkdtemp()
    subprocess.run(['/tmp/s40/tactus_staged', 'render', song + '/mix.wav', '--stem', 'drums=' + song + '/drums.wav', '--map', 'crates/tactus-glove/maps/drums-only.toml', '-o', d + '/p.json', '--features', d + '/f.json'], check=True, capture_output=True)
    got = set(np.round(json.load(open(d + '/f.json'))['onsets_s']['snare'], 3))
    for t in want:
        true = len(ref) and np.min(np.abs(ref - t)) <= 0.05
        k = 'kept' if round(t, 3) in got else 'gated'
        tot[k] += 1; tot[k + '_true'] += int(bool(true))
print(tot)

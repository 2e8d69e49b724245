"""The engine's snare onsets with the staged default model against stage2.py's, on held-out
songs' drum stems: `python3 engine_check.py TACTUS MODEL STAGE2.json SONG_DIR...` (needs the
release binary built with MODEL embedded, and numpy). `render` passes the transcriber's
onsets through the drum track's RMS gate, which can only remove some (quiet ghost notes
under the gate), so every engine onset must be one of stage2.py's, and on songs the gate
leaves alone the two lists are equal. Exit status 1 if an engine onset is not stage2.py's."""
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..', 'lofo'), os.path.join(HERE, '..', '..')]
import stage2 as S  # noqa: E402
import train as T  # noqa: E402

ROOT = os.path.join(HERE, '..', '..', '..', '..')
tactus, model, stage = sys.argv[1:4]
ps, thr = T.read_model(model)
st = json.load(open(stage))
worst = 0
for song in sys.argv[4:]:
    fam, name = song.rstrip('/').split('/')[-2:]
    mel = T.features(song, 'iso', os.path.join(tempfile.gettempdir(), 'engine_check', fam, name + '.iso.f32'))
    acts = T.activations(ps, mel)
    hops, X, _ = S.cands(acts, 1, [], st['k'], st['low'])
    cw = st['classes']['snare']
    want = sorted(hops[S.score(cw, X) >= cw['cut']] * T.HOP_S)
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([tactus, 'render', os.path.join(song, 'mix.wav'), '--stem',
                        'drums=' + os.path.join(song, 'drums.wav'), '--map',
                        os.path.join(ROOT, 'crates', 'tactus-glove', 'maps', 'drums-only.toml'),
                        '-o', os.path.join(d, 'p.json'), '--features', os.path.join(d, 'f.json')],
                       check=True, capture_output=True)
        got = sorted(json.load(open(os.path.join(d, 'f.json')))['onsets_s']['snare'])
    extra = len(set(np.round(got, 3)) - set(np.round(want, 3)))
    gated = len(set(np.round(want, 3)) - set(np.round(got, 3)))
    worst = max(worst, extra)
    print(f'{fam}/{name}: train.py + stage2.py {len(want)} snare onsets, engine {len(got)}; '
          f'engine onsets not stage2.py\'s: {extra}; removed by the gate: {gated}')
print('worst', worst)
sys.exit(1 if worst else 0)

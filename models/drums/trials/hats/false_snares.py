"""Where a binary's false snares sit on the isolated drum stem (issue 10 error analysis):
each detected snare with no true snare within +-50 ms, by the set of (class, GM note) of the
true hits within +-50 ms of it, most common first.

    python3 models/drums/trials/hats/false_snares.py BIN SONG_DIR...
"""
import collections
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', '..')
MAP = os.path.join(ROOT, 'crates', 'tactus-glove', 'maps', 'drums-only.toml')
binary, songs = sys.argv[1], sys.argv[2:]
kinds, n_false = collections.Counter(), 0
with tempfile.TemporaryDirectory() as tmp:
    for s in songs:
        feat = os.path.join(tmp, 'f.json')
        subprocess.run([binary, 'render', os.path.join(s, 'mix.wav'), '--stem', 'drums=' + os.path.join(s, 'drums.wav'),
                        '--map', MAP, '--features', feat, '-o', os.path.join(tmp, 'p.json')], check=True, capture_output=True)
        est = json.load(open(feat))['onsets_s']['snare']
        truth = json.load(open(os.path.join(s, 'truth.json')))['onsets']
        hits = [(h['time_s'], c, h['note']) for c, L in truth.items() for h in L]
        snares = [h['time_s'] for h in truth['snare']]
        for e in est:
            if any(abs(e - x) <= 0.05 for x in snares):
                continue
            n_false += 1
            kinds[tuple(sorted({(c, n) for (t, c, n) in hits if abs(t - e) <= 0.05}))] += 1
print(f'{len(songs)} songs, {n_false} false snares')
for k, v in kinds.most_common(12):
    print(f'{v:5d}  ' + (' + '.join(f'{c} {n}' for c, n in k) or 'nothing'))

"""What a closed hi-hat (GM 42) and a snare (GM 38) add to the spectrum, kit family by kit
family (issue 10 error analysis, 2026-12-02): for each hit of velocity >= 60 with no other
hit within 80 ms, the power that the two frames after the hit add over the frames before it,
per log mel band (train.py's features of the isolated drum stem), in nepers below the
strongest band; the median over hits, every third band (band 0 ~ 30 Hz ... band 45 ~ 15 kHz).

    corpus/.venv/bin/python models/drums/trials/hats/onset_spectra.py [DATA]

DATA: a corpus/drums.py directory whose features train.py has dumped (default
/work/data/drums, the Rebuild data: its fluid and musescore songs are spent held-out songs,
looked at here for the analysis only).
"""
import glob
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
import train as T  # noqa: E402

D = sys.argv[1] if len(sys.argv) > 1 else '/work/data/drums'


def added(fam, kit, note):
    out = []
    for s in sorted(glob.glob(f'{D}/{fam}/{kit}*')):
        t = json.load(open(s + '/truth.json'))
        m = T.features(s, 'iso', f'{D}/.features/{fam}/{os.path.basename(s)}.iso.f32')
        hits = [(h['time_s'], h['note'], h['velocity']) for L in t['onsets'].values() for h in L]
        for (ts, n, v) in hits:
            if n != note or v < 60 or any(abs(ts - x) < 0.08 and nn != n for (x, nn, _) in hits):
                continue
            i = int(round(ts / T.HOP_S))
            if i < 3 or i + 3 >= len(m):
                continue
            pre, post = m[i - 3:i - 1].max(0), m[i + 1:i + 3].max(0)
            p = np.log(np.maximum(np.exp(2 * post) - np.exp(2 * pre), 1e-12)) / 2
            out.append(p - p.max())
    return np.array(out)


for fam, kit in [('fluid', 'std00'), ('fluid', 'power16'), ('fluid', 'room08'), ('fluid', 'jazz32'),
                 ('musescore', 'std00'), ('timgm', ''), ('csound', ''), ('sonicpi', '')]:
    h, s = added(fam, kit, 42), added(fam, kit, 38)
    if len(h) == 0 or len(s) == 0:
        continue
    print(f'{fam:9s} {kit:7s} closed hat (n={len(h):3d}): ' + ' '.join('%3.0f' % x for x in np.median(h, 0)[::3]))
    print(f'{"":17s} snare (n={len(s):3d}): ' + ' '.join('%3.0f' % x for x in np.median(s, 0)[::3]))

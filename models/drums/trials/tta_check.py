"""RULE_tta.md's and RULE_tta_live.md's engine check: the engine's activations for a retuned file
(`drum_features SONG OUT iso|sep MODEL`, the transcriber as the engine runs it) against
`models/drums/tta.py`'s (numpy, from the dumped features). Run from the repository root:

    corpus/.venv/bin/python models/drums/trials/tta_check.py MODEL SONG_DIR...
"""
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, 'models/drums')
import train as T  # noqa: E402

model = sys.argv[1]
ps, thr = T.read_model(model)
assert T.RATIOS != [1.0], 'not a retuned file'
worst = 0.0
for sd in sys.argv[2:]:
    for cond in ('iso', 'sep'):
        with tempfile.TemporaryDirectory() as tmp:
            mel = T.features(sd, cond, os.path.join(tmp, 'm.f32'))
            if T.SHORT:  # a short-view model: the 1024-point view beside (RULE_tta_live.md)
                short = T.features(sd, f'{cond}-short', os.path.join(tmp, 's.f32'))
                n = min(len(mel), len(short))
                mel = np.concatenate([mel[:n], short[:n]], axis=1)
            py = T.activations(ps, mel)
            out = os.path.join(tmp, 'a.f32')
            src = os.path.join(sd, 'drums.wav' if cond == 'iso' else 'mix.wav')
            subprocess.run([T.dumper_path(), src, out, cond, model], check=True)
            rs = np.fromfile(out, '<f4').reshape(-1, 4)
        m = min(len(py), len(rs))
        d = float(np.abs(py[:m] - rs[:m]).max())
        worst = max(worst, d)
        print(f'{sd} {cond}: hops {len(py)} / {len(rs)}, max |engine - train.py| {d:.2e}')
print(f'worst {worst:.2e}')

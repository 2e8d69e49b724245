"""The engine's activations for a drum model file (`drum_features SONG OUT iso|sep MODEL`,
the transcriber as the engine runs it) against train.py's (numpy, from the dumped features),
for any model train.py reads: plain, with the short view, retuned. Used by short_check.py
(RULE_short.md, RULE_short_live.md) and tta_check.py (RULE_tta.md, RULE_tta_live.md).
"""
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, 'models/drums')
import train as T  # noqa: E402


def compare(model, song_dirs, expect=None):
    """Prints the largest |engine - train.py| per song and condition; returns the worst.
    expect(T) may assert something of the model read (its kind)."""
    ps, _ = T.read_model(model)
    if expect:
        expect(T)
    worst = 0.0
    for sd in song_dirs:
        for cond in ('iso', 'sep'):
            with tempfile.TemporaryDirectory() as tmp:
                mel = T.features(sd, cond, os.path.join(tmp, 'm.f32'))
                if T.SHORT:  # the 1024-point view beside the 2048-point one
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
    return worst

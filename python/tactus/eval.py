"""The metrics of ``tactus eval``, from Python (the same Rust code; checked against
mir_eval by ``crates/tactus-eval/tests/mir_eval_oracle.py``).

    from tactus import eval as te
    te.onset_scores(ref_times, est_times)          # {"precision", "recall", "f_measure", "matched"}
    te.melody_scores(ref_hz, est_hz)               # raw pitch/chroma accuracy, voicing
    te.level_accuracy(truth_levels, est_levels)    # (exact, within one level)
    te.sdr_db(reference, estimate)                 # signal-to-distortion ratio
    te.evaluate(result_or_features_json, truth)    # the whole report of `tactus eval --truth`
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Sequence, Tuple, Union

import numpy as np

from . import _native

__all__ = ["onset_scores", "melody_scores", "level_accuracy", "sdr_db", "evaluate"]


def onset_scores(
    reference: Sequence[float], estimate: Sequence[float], window_s: float = 0.05
) -> Dict[str, float]:
    """Onset precision, recall and F-measure within ``window_s`` (mir_eval.onset.f_measure)."""
    return json.loads(
        _native.onset_scores(
            [float(x) for x in reference], [float(x) for x in estimate], float(window_s)
        )
    )


def melody_scores(
    ref_hz: Sequence[float], est_hz: Sequence[float], cent_tolerance: float = 50.0
) -> Dict[str, float]:
    """Raw pitch accuracy, raw chroma accuracy, voicing recall and false alarm of
    ``est_hz`` against ``ref_hz`` on the same hop (0 = unvoiced; mir_eval.melody)."""
    return json.loads(
        _native.melody_scores(
            [float(x) for x in ref_hz], [float(x) for x in est_hz], float(cent_tolerance)
        )
    )


def level_accuracy(truth: Sequence[int], estimate: Sequence[int]) -> Tuple[float, float]:
    """Fraction of bins whose level is exact, and within one level."""
    return _native.level_accuracy([int(x) for x in truth], [int(x) for x in estimate])


def sdr_db(reference: Any, estimate: Any) -> float:
    """Signal-to-distortion ratio of ``estimate`` against ``reference``, in dB."""
    r = np.asarray(reference, dtype=np.float32).ravel().tolist()
    e = np.asarray(estimate, dtype=np.float32).ravel().tolist()
    return _native.sdr_db(r, e)


def _text(x: Any) -> str:
    if hasattr(x, "features_json"):
        return x.features_json
    if isinstance(x, dict):
        return json.dumps(x)
    if isinstance(x, (str, os.PathLike)) and os.path.exists(x):
        p = os.fspath(x)
        if os.path.isdir(p):
            p = os.path.join(p, "truth.json")
        with open(p, encoding="utf-8") as f:
            return f.read()
    return str(x)


def evaluate(features: Union[Any, str], truth: Union[str, "os.PathLike[str]", dict]) -> Dict:
    """The report of ``tactus eval FEATURES --truth TRUTH --json``: ``features`` is a
    :class:`tactus.Result`, a features file path or its JSON text; ``truth`` a corpus song
    folder, a ``truth.json`` path, its text or a dict."""
    return json.loads(_native.eval_report(_text(features), _text(truth)))

"""RULE_tta.md's and RULE_tta_live.md's engine check: the engine's activations for a retuned
file (plain or short-view network inside) against train.py's (`engine_check.py`). Run from
the repository root:

    corpus/.venv/bin/python models/drums/trials/tta_check.py MODEL SONG_DIR...
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from engine_check import compare  # noqa: E402


def retuned(T):
    assert T.RATIOS != [1.0], 'not a retuned file'


compare(sys.argv[1], sys.argv[2:], retuned)

"""RULE_short.md's engine check: the engine's activations for a short-view model
(`drum_features SONG OUT iso|sep MODEL`, the transcriber as the engine runs it) against
train.py's (numpy, from the dumped 2048- and 1024-point features; `engine_check.py`). Run
from the repository root:

    corpus/.venv/bin/python models/drums/trials/short_check.py MODEL SONG_DIR...
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from engine_check import compare  # noqa: E402


def short(T):
    assert T.SHORT, "not a short-view model"


compare(sys.argv[1], sys.argv[2:], short)

"""What the LOFO analysis scripts share: train.py and fastpick on the path, the folder of fold
models and caches (LOFO_DIR), and the out-of-family activations that oof.py pickles
({(family, song, cond): (activations, truth, the fold's thresholds)})."""
import os
import pickle
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..'), HERE]
DIR = os.environ.get('LOFO_DIR', '/tmp/lofo')  # fold models and caches (lofo.sh writes them)
GRID = np.arange(0.1, 0.951, 0.025)  # thresholds tried per song


def load(paths):
    D = {}
    for f in paths:
        with open(f, 'rb') as fh:
            D.update(pickle.load(fh))
    return D


def lg(p):
    p = np.clip(p, 1e-4, 1 - 1e-4)
    return np.log(p / (1 - p))

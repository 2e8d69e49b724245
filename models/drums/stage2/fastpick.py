"""Peak picking (train.py's pick, drums.rs' Picker) and greedy matching (train.py's match)
compiled with numba when it is installed (the LOFO scripts score thousands of songs x
thresholds); the same code runs as plain Python without it. Checked against train.py's own
pick + match on random activations (the check at the end: python3 fastpick.py)."""
import numpy as np
try:
    import numba
    njit = numba.njit(cache=True)
except ImportError:  # plain Python: the same answers, slower
    def njit(f):
        return f
HOP = 0.01
@njit
def pick(a, thr, min_gap=5):
    out = np.empty(len(a), np.int64); n = 0
    armed = True; peak = 0.0; last = -1
    for i in range(len(a)):
        x = a[i]
        if not armed:
            peak = max(peak, x)
            if x < thr or x < 0.5 * peak:
                armed = True
        if armed and x >= thr and (last < 0 or i - last >= min_gap):
            armed = False; peak = x; last = i
            out[n] = i; n += 1
    return out[:n]

@njit
def match(est, ref, tol=0.05):
    used = np.zeros(len(ref), np.bool_)
    tp = 0; j0 = 0
    for e in est:
        while j0 < len(ref) and ref[j0] < e - tol:
            j0 += 1
        j = j0
        while j < len(ref) and ref[j] <= e + tol:
            if not used[j]:
                used[j] = True; tp += 1; break
            j += 1
    return np.array([tp, len(est) - tp, len(ref) - tp])

def counts(a, ref, th):
    est = pick(a.astype(np.float64), float(th)) * HOP
    return match(est, np.sort(np.asarray(ref, np.float64)))


if __name__ == "__main__":
    import os, sys
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    import train as T
    rng = np.random.default_rng(0)
    for k in range(200):
        a = rng.random(3000).astype(np.float32) ** 3
        ref = sorted(rng.random(50) * 30)
        th = rng.uniform(0.1, 0.9)
        est = [i * 0.01 for i in T.pick(a, th)]
        assert list(counts(a, ref, th)) == list(T.match(est, ref)), k
    print("fastpick = train.py's pick + match on 200 random songs")

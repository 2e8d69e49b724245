"""Out-of-family F per condition from oof.py's pickles, before and after a snare judge
(the screen of RULE_stage2_live.md, which scored each condition apart, kept as a script):

    STAGE2_HIDDEN=32 python oof_conds.py K LOW PICKLE

Prints, per condition (iso, sep, mix, as the pickle holds them), the four classes' F against
each fold's own thresholds, then the snare's F through a judge with wait K and candidates at
LOW, learnt family by family on the other four families (stage2.py's recipe), and the mean
of the conditions' snare F with the judge."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(HERE, '..', '..'), HERE]
import fastpick as fast  # noqa: E402
import stage2 as S  # noqa: E402
import train as T  # noqa: E402

k, low, pickles = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3:]
S.CLASSES_ONLY = []  # every class's rows, for the F before any judge
rows = S.load_rows(pickles, k, low)
conds = sorted({r['cond'] for r in rows}, key=['iso', 'sep', 'mix'].index)
snare = T.CLASSES.index('snare')
judged = S.judged_out_of_family(rows, snare)
after = []
for cond in conds:
    pre = [T.prf(*sum(fast.counts(r['a'], r['ref'], r['g']) for r in rows if r['cond'] == cond and r['c'] == c))[2]
           for c in range(4)]
    post = T.prf(*sum(judged[id(r)] for r in rows if r['cond'] == cond and r['c'] == snare))[2]
    after.append(post)
    print(f'{cond}: kick {pre[0]:.3f} snare {pre[1]:.3f} toms {pre[2]:.3f} cymbals {pre[3]:.3f}'
          f' | snare with the judge (wait {k}) {post:.3f}')
print(f'mean of the snare with the judge: {sum(after) / len(after):.4f}')

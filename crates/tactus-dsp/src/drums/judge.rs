//! The second stage of a staged model file (`"TACTUSD2"`, step 5 of the module docs): a
//! judge per class that decides, a few hops later, which of the candidates picked at a low
//! threshold are onsets, and the running state that feeds it.

use super::picker::Picker;
use super::{DrumFrame, CLASSES};

/// Features of a [`Judge`]: the four classes' logits, a bias, the four logits minus the
/// song's running mean (shrunk), and the shrink factor.
pub const JUDGE_INPUTS: usize = 2 * CLASSES + 2;

/// The largest number of hidden units a [`Judge`] may have.
pub(super) const JUDGE_MAX_HIDDEN: usize = 256;

/// The second stage's decision for one class (see [`SecondStage`]): a linear score of the
/// [`JUDGE_INPUTS`] features (a logistic regression), or a perceptron with one hidden layer
/// of ReLU units on them.
#[derive(Clone, Debug, PartialEq)]
pub struct Judge {
    /// The hidden units, each its weights over the features and then its bias; empty for a
    /// linear judge.
    pub hidden: Vec<[f32; JUDGE_INPUTS + 1]>,
    /// The output's weights: over the features for a linear judge, else one per hidden unit.
    pub w: Vec<f32>,
    /// The output's bias (a linear judge's features hold their own bias: 0 there).
    pub bias: f32,
    /// A candidate is an onset where the score reaches this.
    pub cut: f32,
}

impl Judge {
    /// A linear judge: the score is `w · x`.
    pub fn linear(w: [f32; JUDGE_INPUTS], cut: f32) -> Judge {
        Judge {
            hidden: Vec::new(),
            w: w.to_vec(),
            bias: 0.0,
            cut,
        }
    }

    /// The score of the features `x`, in f64: `w · x` for a linear judge, else
    /// `bias + Σ_h w_h · max(0, hidden_h · x + hidden bias_h)`.
    pub fn score(&self, x: &[f64; JUDGE_INPUTS]) -> f64 {
        let dot = |w: &[f32]| -> f64 { w.iter().zip(x).map(|(&w, &x)| w as f64 * x).sum() };
        if self.hidden.is_empty() {
            return dot(&self.w);
        }
        let mut z = self.bias as f64;
        for (unit, &w) in self.hidden.iter().zip(&self.w) {
            let h = dot(&unit[..JUDGE_INPUTS]) + unit[JUDGE_INPUTS] as f64;
            z += w as f64 * h.max(0.0);
        }
        z
    }
}

/// A second stage for some classes' onsets, learnt on *out-of-family* activations (each
/// training kit family scored by a network that never heard it, `models/drums/stage2/
/// stage2.py`; `docs/decisions/0047-snare-second-stage.md`): on an unheard kit the network's
/// activations are biased in a way its own training kits do not show, and this stage has
/// seen how.
///
/// For a judged class `c`: the candidates are the onsets of a `Picker` at threshold
/// `low`; candidate hop `i` waits `wait` hops, then its features are the logits `l` of the
/// four classes' largest activation over hops `i ..= i + wait`, a bias 1, the same `l` minus
/// the mean of `l` over the song's earlier candidates of class `c`, times `m / (m + shrink)`
/// (`m`: how many there were; the mean is 0 when `m = 0`), and that factor. Logits are
/// taken of the activation clamped to [1e-4, 0.9999]. The candidate is an onset where
/// the [`Judge`]'s score reaches its `cut`. Causal; every class's output is delayed by
/// `wait` hops, so the transcriber's latency grows by `wait` hops. Classes without a judge
/// keep the model's own picker.
#[derive(Clone, Debug, PartialEq)]
pub struct SecondStage {
    /// Hops a candidate waits before it is judged.
    pub wait: usize,
    /// The candidates' picker threshold.
    pub low: f32,
    /// The running mean's shrink count.
    pub shrink: f32,
    /// Per class: its judge, or `None` for the model's own picker.
    pub judges: [Option<Judge>; CLASSES],
}

/// The running state of a [`SecondStage`].
pub(super) struct Staged {
    /// The activations of the last `wait + 1` hops, hop `i` at `i % (wait + 1)`.
    pub(super) ring: Vec<[f32; CLASSES]>,
    /// The candidates' pickers (threshold `low`).
    low: [Picker; CLASSES],
    /// Per judged class: the sum of its earlier candidates' logits, and how many there were.
    sums: [[f64; CLASSES]; CLASSES],
    seen: [usize; CLASSES],
    /// Hops emitted.
    pub(super) emitted: usize,
}

/// The logit of an activation clamped to [1e-4, 0.9999] (`stage2.py`'s `lg`, in f32 as
/// numpy computes it on f32 activations).
fn logit(a: f32) -> f32 {
    let p = a.clamp(1e-4, 0.9999);
    (p / (1.0 - p)).ln()
}

impl Staged {
    pub(super) fn new(stage: &SecondStage) -> Staged {
        Staged {
            ring: vec![[0.0; CLASSES]; stage.wait + 1],
            low: [Picker::NEW; CLASSES],
            sums: [[0.0; CLASSES]; CLASSES],
            seen: [0; CLASSES],
            emitted: 0,
        }
    }

    /// Back to the start of a stream, keeping the ring's memory.
    pub(super) fn clear(&mut self) {
        self.ring.fill([0.0; CLASSES]);
        self.low = [Picker::NEW; CLASSES];
        self.sums = [[0.0; CLASSES]; CLASSES];
        self.seen = [0; CLASSES];
        self.emitted = 0;
    }

    /// Decides hop `j`, whose activations and those of the hops after it up to `end`
    /// (exclusive, at most `wait` more) are in the ring; emits it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn decide(
        &mut self,
        stage: &SecondStage,
        pickers: &mut [Picker; CLASSES],
        thresholds: &[f32; CLASSES],
        min_gap: usize,
        j: usize,
        end: usize,
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        let k = self.ring.len();
        let act = self.ring[j % k];
        let mut f = DrumFrame {
            activation: act,
            onset: [false; CLASSES],
        };
        for c in 0..CLASSES {
            let Some(judge) = &stage.judges[c] else {
                f.onset[c] = pickers[c].step(j, act[c], thresholds[c], min_gap);
                continue;
            };
            if !self.low[c].step(j, act[c], stage.low, min_gap) {
                continue;
            }
            let mut peak = act;
            for h in j + 1..end {
                for (p, &x) in peak.iter_mut().zip(&self.ring[h % k]) {
                    *p = p.max(x);
                }
            }
            let l = peak.map(|x| logit(x) as f64);
            let m = self.seen[c] as f64;
            let sh = m / (m + stage.shrink as f64);
            let mut x = [0f64; JUDGE_INPUTS];
            x[CLASSES] = 1.0;
            x[2 * CLASSES + 1] = sh;
            for (i, &li) in l.iter().enumerate() {
                let mean = if self.seen[c] > 0 {
                    self.sums[c][i] / m
                } else {
                    0.0
                };
                x[i] = li;
                x[CLASSES + 1 + i] = sh * (li - mean);
                self.sums[c][i] += li;
            }
            self.seen[c] += 1;
            let z = judge.score(&x);
            f.onset[c] = z >= judge.cut as f64;
        }
        self.emitted = j + 1;
        emit(j, f);
    }
}

//! Pitch discretization: f0 in Hz → Level `0..=levels` (0 = unvoiced).
//!
//! **Algorithm** (the paper, §2: "eight discrete levels … relative to the maximum pitch";
//! §4: "only the non-zero pitch ranges are considered"). The stem's non-zero pitch range
//! `[lo, hi]` is cut into `levels` equal-width intervals and a voiced hop gets the 1-based index
//! of the interval holding its pitch: `level = ⌊levels · t⌋ + 1`, clamped to `1..=levels`, where
//! * [`Scale::Semitones`] (default, docs/design.md): `t = log2(f0 / lo) / log2(hi / lo)`, i.e. equal
//!   musical intervals (100–400 Hz with 8 levels: 3 semitones per level);
//! * [`Scale::LinearHz`]: `t = (f0 − lo) / (hi − lo)`, equal widths in Hz (closer to the paper's
//!   literal "percentile relative to the maximum pitch").
//!
//! Intervals are half-open, `[edge_j, edge_{j+1})`, so a pitch exactly on an inner edge belongs to
//! the upper level, and `hi` itself to the top level. Computed in `f64`.
//!
//! **Special cases.** Unvoiced input (f0 ≤ 0, NaN or ±∞) → 0. Pitches outside the range are
//! clamped to level 1 or `levels`. A degenerate range — `lo == hi`, a non-finite bound, or (in
//! semitone mode) a bound ≤ 0 — maps every voiced pitch to **level 1**, the level `lo` itself
//! gets in a proper range; a reversed range is swapped first.
//!
//! **Range.** Offline ([`range_offline`], paper-faithful): min and max of the track's voiced
//! pitch, after the gate and Tukey's fences. Streaming ([`RunningRange`]): running min and max of
//! the voiced pitches seen so far (it only widens; call `reset()` between songs).
//!
//! **Streaming range with a prior** ([`PriorRange`], our addition). The running min and max
//! start from one note: the first note lands on level 1 (a one-note range) and every new
//! extreme shifts every level. `PriorRange` pads the running range, symmetrically in
//! semitones, up to a prior span `span_st` (the width a melodic line usually covers, e.g.
//! 20 semitones for a bass line), and lets the padding fade as voiced hops accumulate:
//! `pad = max(0, span_st − (hi − lo)) · fade / (fade + n) / 2` semitones on each side after
//! `n` voiced hops. A line wider than the prior is not padded at all; a narrower one
//! converges to its own min and max. Causal, allocation-free, O(1) per hop.
//!
//! **Running quantiles** ([`QuantileRange`], [`PriorRange::with_quantile`], our addition). The
//! running min and max keep every early octave error for the rest of the song. The offline
//! rule's 1st–99th percentile range can be followed causally instead: the quantiles of every
//! voiced hop seen so far (not of a window), from a histogram of 1/8-semitone cells that also
//! keeps each cell's smallest and largest value. The low end is the smallest value of the cell
//! holding the `round((n − 1)·p)`-th smallest pitch, the high end the largest value of the cell
//! holding its mirror, so the range is never narrower than the exact quantiles and at most one
//! cell (12.5 cents) wider; with fewer than `1/(2p)` values it is the exact min and max. It
//! converges to the offline range as the song goes on. O(cells) per hop, no allocation after
//! construction.
//!
//! **Range from held notes** ([`HeldRange`], [`range_quantiles_held`], our addition;
//! `docs/decisions/0019-clean-bass-range-from-held-notes.md`). A hop counts towards the range
//! only when it sits inside a held note: it and the `k` hops on each side are voiced and within
//! `tol_st` semitones of it ([`held_mask`]). A tracker's errors where one note gives way to the
//! next (the bass harmonic-sum tracker's 200 ms frame straddles both and reports their common
//! subharmonic for up to ~100 ms), or a brief spurious island in a rest, then do not widen the
//! range. When fewer than `min_share` of the voiced hops are held (a line of very short notes),
//! every voiced hop counts as before. Offline: the quantiles of the held hops of the whole
//! track. Streaming: hop `i` enters its own [`PriorRange`] once hop `i + k` has arrived (its
//! padding fading with the voiced hops, as the plain one's), beside a [`PriorRange`] of every
//! voiced hop; the held one is used while the held hops seen so far are at least `min_share` of
//! the voiced hops seen so far. No added latency (the range lags by `k` hops); no allocation
//! after construction; `k = 0` is the plain [`PriorRange`].
//!
//! **Range without octave shadows** ([`shadow_mask`], [`range_quantiles_kept`],
//! [`HeldRange::with_shadow`], our addition;
//! `docs/decisions/0026-mix-bass-range-without-octave-shadows.md`). On a mixture a bass tracker
//! sometimes reports the line's own note an octave low for a run of hops (a kick or tom body
//! under the note supplies the subharmonic). A few percent of such hops are enough to put the
//! 1st percentile an octave under the line's lowest note and shift every level. A voiced hop is
//! an *octave shadow* when the line sounds an octave above it (within [`SHADOW_TOL_ST`] of its
//! pitch + 12) within `w` hops on either side; shadows are left out of the range the way unheld
//! hops are (same `min_share` and `min_hops` fallback). A line that really drops an octave
//! within `w` hops loses that low note from its range; a line that alternates root and octave
//! throughout falls back to every voiced hop (too few kept). Streaming: hop `i` is judged once
//! hop `i + max(k, w)` has arrived (no added latency; the range lags by that many hops, and the
//! first `max(k, w)` hops of a stream never count).
//!
//! **Range from held or agreed hops** ([`agree_mask`], [`range_quantiles_kept_or`],
//! [`HeldRange::update_trusted`], our addition;
//! `docs/decisions/0029-mix-lead-range-from-held-or-agreed-hops.md`). A mixture's lead, tracked
//! by one tracker for its pitch and a second one for its voicing, follows another instrument or
//! an octave for short stretches; those set the range's ends. Held notes alone leave them out,
//! but also a fast line's true extremes (eighths at 132 bpm hold for about 23 hops). A hop
//! therefore also counts when the second tracker's pitch agrees with it within `tol_st`
//! semitones: its pitch has two witnesses however short the note. Offline and streaming as the
//! held range (same fallbacks, same lag); a hop that is neither held nor agreed is left out.
//!
//! **Narrowed to the sure hops** ([`range_quantiles_kept_or_sure`], [`narrow_range`],
//! [`HeldRange::update_sure`], our addition;
//! `docs/decisions/0038-mix-lead-range-narrowed-to-sure-hops.md`). A learned tracker knows how
//! sure it is of a pitch (the network's probability near the decided candidate,
//! `tactus_dsp::shs` module docs, "Learned salience"). On a mixture's lead the unsure hops are
//! mostly where it sits on a chord tone, an octave or the bass while the voice rests or is
//! masked, and those set the range's ends even when they are held or agreed, sometimes many
//! semitones past the voice. But a voice's own extremes can be unsure too (a soprano's low
//! notes under the alto), and dropping them narrows a short range. So the range of the held or
//! agreed hops is narrowed to at most `margin` semitones beyond the range of those of them that
//! are also sure: the held test still reads every voiced hop, and the fallbacks are unchanged.
//! A mixture's bass line uses the bottom only: its unsure hops under the line are a kick's body
//! or a subharmonic, but its unsure high notes are real. Streaming, a second [`HeldRange`] fed
//! the same hops keeps only the sure ones ([`HeldRange::update_sure`]), and the running range
//! is narrowed to it once it holds ([`HeldRange::holds`]); leaving the unsure hops out of the
//! running range itself delays it and drops early extremes.
//!
//! **Register prior** ([`RangePrior::Register`], [`PriorRange::with_prior`], our addition;
//! `docs/decisions/0022-streaming-levels-from-a-register-prior.md`). A span prior pads the
//! first notes symmetrically, but where a line starts says little about which way it will go: a
//! bass line that opens on its lowest roots only climbs. A register prior knows the
//! instrument's usual compass `[r_lo, r_hi]` instead: each end of the running (quantile) range
//! starts at the register's edge and moves to the line's own end as voiced hops accumulate,
//! `lo' = lo − w·max(0, lo − r_lo)` (and mirrored for `hi`) in semitones, with the same weight
//! `w = fade / (fade + n)`. The range is never narrower than the line's own, an end beyond the
//! register is kept, and the prior fades to nothing. Causal, O(1) on top of the quantile range,
//! no allocation after construction.
//!
//! **Defaults.** [`DEFAULT_LEVELS`] = 8 (paper), semitone scale (docs/design.md). **Latency:** none.

use crate::ConfigError;

/// The paper's number of pitch levels.
pub const DEFAULT_LEVELS: u8 = 8;

/// How the pitch range is cut into levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Scale {
    /// Equal musical intervals (log frequency). The default.
    #[default]
    Semitones,
    /// Equal widths in Hz.
    LinearHz,
}

/// Maps pitch to levels. See the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Discretizer {
    levels: u8,
    scale: Scale,
}

impl Default for Discretizer {
    /// 8 levels, semitone scale.
    fn default() -> Self {
        Discretizer {
            levels: DEFAULT_LEVELS,
            scale: Scale::Semitones,
        }
    }
}

impl Discretizer {
    /// A discretizer with `levels` voiced levels (1..=255). Errors when `levels == 0`.
    pub fn new(levels: u8, scale: Scale) -> Result<Self, ConfigError> {
        if levels == 0 {
            return Err(ConfigError::invalid("levels", "must be at least 1"));
        }
        Ok(Discretizer { levels, scale })
    }

    /// Number of voiced levels.
    pub fn levels(&self) -> u8 {
        self.levels
    }

    /// The scale.
    pub fn scale(&self) -> Scale {
        self.scale
    }

    /// Level of `f0_hz` within `range = (lo, hi)` in Hz: 0 when unvoiced, else `1..=levels`.
    #[inline]
    pub fn level(&self, f0_hz: f32, range: (f32, f32)) -> u8 {
        if !(f0_hz.is_finite() && f0_hz > 0.0) {
            return 0;
        }
        let (lo, hi) = if range.0 <= range.1 {
            range
        } else {
            (range.1, range.0)
        };
        if !(lo.is_finite() && hi.is_finite()) || lo == hi {
            return 1;
        }
        let (f, lo, hi) = (f64::from(f0_hz), f64::from(lo), f64::from(hi));
        let t = match self.scale {
            Scale::Semitones => {
                if lo <= 0.0 {
                    return 1;
                }
                (f / lo).log2() / (hi / lo).log2()
            }
            Scale::LinearHz => (f - lo) / (hi - lo),
        };
        let n = f64::from(self.levels);
        // `t` is finite here (f, lo, hi finite, hi > lo); the clamp also covers t < 0 and t ≥ 1.
        ((n * t).floor() + 1.0).clamp(1.0, n) as u8
    }
}

/// Offline range: `(min, max)` of the voiced (finite, > 0) values, `None` if there are none.
/// Does not allocate.
pub fn range_offline(f0_hz: &[f32]) -> Option<(f32, f32)> {
    let mut r = RunningRange::new();
    let mut out = None;
    for &f in f0_hz {
        out = r.update(f);
    }
    out
}

/// Offline range from quantiles: `(q(p), q(1 − p))` of the voiced (finite, > 0) values, the
/// `round((n − 1)·p)`-th smallest and its mirror; `None` if there are none. `p = 0` is
/// [`range_offline`]. Allocates a sorted copy of the voiced values.
pub fn range_quantiles(f0_hz: &[f32], p: f32) -> Option<(f32, f32)> {
    let mut v: Vec<f32> = f0_hz
        .iter()
        .copied()
        .filter(|f| f.is_finite() && *f > 0.0)
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f32::total_cmp);
    let p = if p.is_finite() {
        p.clamp(0.0, 0.5)
    } else {
        0.0
    };
    let k = ((v.len() - 1) as f32 * p).round() as usize;
    Some((v[k], v[v.len() - 1 - k]))
}

/// Longest `k` of [`HeldRange`] and [`held_mask`].
pub const MAX_HELD_HOPS: usize = 16;

fn semitones(f0_hz: f32) -> Option<f32> {
    (f0_hz.is_finite() && f0_hz > 0.0).then(|| crate::hz_to_semitones(f0_hz))
}

/// Whether each hop sits inside a held note: it and the `k` hops on each side are voiced and
/// within `tol_st` semitones of it (module docs, "Range from held notes"). Hops within `k`
/// of either end are not held (for `k > 0`). Allocates the result.
pub fn held_mask(f0_hz: &[f32], k: usize, tol_st: f32) -> Vec<bool> {
    let n = f0_hz.len();
    (0..n)
        .map(|i| {
            let Some(c) = semitones(f0_hz[i]) else {
                return false;
            };
            if i < k || i + k >= n {
                return k == 0;
            }
            f0_hz[i - k..=i + k]
                .iter()
                .all(|&f| semitones(f).is_some_and(|x| (x - c).abs() <= tol_st))
        })
        .collect()
}

/// Longest `w` of [`HeldRange::with_shadow`] and [`shadow_mask`].
pub const MAX_SHADOW_HOPS: usize = 32;

/// Semitones within which a hop's octave counts as sounding ([`shadow_mask`]).
pub const SHADOW_TOL_ST: f32 = 1.0;

/// Whether each hop is an *octave shadow*: it is voiced and some voiced hop at most `w` hops
/// away (either side, itself excluded) lies within [`SHADOW_TOL_ST`] semitones of its pitch
/// + 12 (module docs, "Range without octave shadows"). `w = 0`: no hop is. Allocates.
pub fn shadow_mask(f0_hz: &[f32], w: usize) -> Vec<bool> {
    let st: Vec<Option<f32>> = f0_hz.iter().map(|&f| semitones(f)).collect();
    (0..st.len())
        .map(|i| {
            let Some(c) = st[i] else {
                return false;
            };
            let (a, b) = (i.saturating_sub(w), (i + w).min(st.len().saturating_sub(1)));
            w > 0
                && st[a..=b]
                    .iter()
                    .any(|x| x.is_some_and(|x| (x - (c + 12.0)).abs() <= SHADOW_TOL_ST))
        })
        .collect()
}

/// [`range_quantiles`] of the held hops ([`held_mask`]) when there are at least `min_hops`
/// (and one) of them and they are at least `min_share` of the voiced hops, else of every
/// voiced hop. Allocates.
pub fn range_quantiles_held(
    f0_hz: &[f32],
    p: f32,
    k: usize,
    tol_st: f32,
    min_share: f32,
    min_hops: u64,
) -> Option<(f32, f32)> {
    range_quantiles_kept(f0_hz, p, k, tol_st, 0, min_share, min_hops)
}

/// Whether each hop is voiced in both tracks (`other_hz` shorter than `f0_hz`: the missing
/// hops are unvoiced) with pitches within `tol_st` semitones of each other (module docs,
/// "Range from held or agreed hops"). Allocates.
pub fn agree_mask(f0_hz: &[f32], other_hz: &[f32], tol_st: f32) -> Vec<bool> {
    f0_hz
        .iter()
        .enumerate()
        .map(|(i, &f)| pitches_agree(f, other_hz.get(i).copied().unwrap_or(0.0), tol_st))
        .collect()
}

/// One hop of [`agree_mask`]: both voiced and within `tol_st` semitones. No allocation.
#[inline]
pub fn pitches_agree(a_hz: f32, b_hz: f32, tol_st: f32) -> bool {
    match (semitones(a_hz), semitones(b_hz)) {
        (Some(a), Some(b)) => (a - b).abs() <= tol_st,
        _ => false,
    }
}

/// [`range_quantiles_held`] where a hop must also not be an octave shadow ([`shadow_mask`]
/// with window `w`) to be kept; `w = 0` is [`range_quantiles_held`], and `k = 0` keeps every
/// voiced hop that is not a shadow. Allocates.
pub fn range_quantiles_kept(
    f0_hz: &[f32],
    p: f32,
    k: usize,
    tol_st: f32,
    w: usize,
    min_share: f32,
    min_hops: u64,
) -> Option<(f32, f32)> {
    range_quantiles_kept_or(f0_hz, &[], p, k, tol_st, w, min_share, min_hops)
}

/// [`range_quantiles_kept`] where a voiced hop marked in `trusted` (its pitch agreed by a
/// second tracker, [`agree_mask`]; hops beyond its end are not) counts as held (module docs,
/// "Range from held or agreed hops"); octave shadows stay out. `trusted = &[]` is
/// [`range_quantiles_kept`]. Allocates.
#[allow(clippy::too_many_arguments)]
pub fn range_quantiles_kept_or(
    f0_hz: &[f32],
    trusted: &[bool],
    p: f32,
    k: usize,
    tol_st: f32,
    w: usize,
    min_share: f32,
    min_hops: u64,
) -> Option<(f32, f32)> {
    range_quantiles_kept_or_sure(f0_hz, trusted, &[], p, k, tol_st, w, min_share, min_hops)
}

/// [`range_quantiles_kept_or`] where only a hop marked in `sure` (its tracker is confident
/// of its pitch; hops beyond its end are) may count as held or agreed (module docs, "Only
/// sure hops"). The held mask is still computed on every voiced hop, so an unsure hop inside
/// a note leaves its neighbours held. `sure = &[]` is [`range_quantiles_kept_or`]. Allocates.
#[allow(clippy::too_many_arguments)]
pub fn range_quantiles_kept_or_sure(
    f0_hz: &[f32],
    trusted: &[bool],
    sure: &[bool],
    p: f32,
    k: usize,
    tol_st: f32,
    w: usize,
    min_share: f32,
    min_hops: u64,
) -> Option<(f32, f32)> {
    let mut mask = held_mask(f0_hz, k, tol_st);
    for (i, m) in mask.iter_mut().enumerate() {
        *m |= trusted.get(i).copied().unwrap_or(false) && semitones(f0_hz[i]).is_some();
        *m &= sure.get(i).copied().unwrap_or(true);
    }
    if w > 0 {
        for (m, s) in mask.iter_mut().zip(shadow_mask(f0_hz, w)) {
            *m &= !s;
        }
    }
    let held: Vec<f32> = f0_hz
        .iter()
        .zip(&mask)
        .filter(|(_, &m)| m)
        .map(|(&f, _)| f)
        .collect();
    let voiced = f0_hz.iter().filter(|f| semitones(**f).is_some()).count();
    if held.len() as u64 >= min_hops.max(1) && held.len() as f32 >= min_share * voiced as f32 {
        range_quantiles(&held, p)
    } else {
        range_quantiles(f0_hz, p)
    }
}

/// `range` narrowed to at most `below_st` semitones under `sure`'s bottom and `above_st`
/// over its top (module docs, "Narrowed to the sure hops"):
/// `(max(lo, lo_s · 2^(−below/12)), min(hi, hi_s · 2^(above/12)))`, in Hz; an infinite
/// margin leaves that end as it is. `range` itself when `sure` is `None` or the narrowed
/// range would be empty.
pub fn narrow_range(
    range: Option<(f32, f32)>,
    sure: Option<(f32, f32)>,
    below_st: f32,
    above_st: f32,
) -> Option<(f32, f32)> {
    let ((lo, hi), (ls, hs)) = (
        range?,
        match sure {
            Some(s) => s,
            None => return range,
        },
    );
    let (a, b) = (
        lo.max(ls / (below_st / 12.0).exp2()),
        hi.min(hs * (above_st / 12.0).exp2()),
    );
    if a <= b {
        Some((a, b))
    } else {
        range
    }
}

/// Streaming range from held notes (module docs, "Range from held notes"): a [`PriorRange`]
/// of the held hops beside one of every voiced hop. Causal, allocation-free after
/// construction.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldRange {
    all: PriorRange,
    held: PriorRange,
    /// Semitones (NaN = unvoiced), Hz, the trusted flag ([`HeldRange::update_trusted`]) and
    /// the sure flag ([`HeldRange::update_sure`]) of the last `2·max(k, w) + 1` hops, hop `i`
    /// at `i % len`.
    ring: [(f32, f32, bool, bool); 2 * MAX_SHADOW_HOPS + 1],
    k: usize,
    /// Octave-shadow window ([`HeldRange::with_shadow`]); 0 = off.
    w: usize,
    tol_st: f32,
    min_share: f32,
    min_hops: u64,
    n_in: usize,
    n_voiced: u64,
    n_held: u64,
}

impl HeldRange {
    /// Module docs, "Range from held notes"; `k = 0`: the plain [`PriorRange::with_quantile`].
    /// Errors as that does, and unless
    /// `k ≤` [`MAX_HELD_HOPS`], `tol_st ≥ 0` and `min_share` in `[0, 1]`.
    pub fn new(
        span_st: f32,
        fade_hops: f32,
        p: f32,
        k: usize,
        tol_st: f32,
        min_share: f32,
        min_hops: u64,
    ) -> Result<Self, ConfigError> {
        Self::with_prior(
            RangePrior::Span(span_st),
            fade_hops,
            p,
            k,
            tol_st,
            min_share,
            min_hops,
        )
    }

    /// As [`HeldRange::new`], both ranges padded towards `prior`
    /// ([`PriorRange::with_prior`]).
    pub fn with_prior(
        prior: RangePrior,
        fade_hops: f32,
        p: f32,
        k: usize,
        tol_st: f32,
        min_share: f32,
        min_hops: u64,
    ) -> Result<Self, ConfigError> {
        if k > MAX_HELD_HOPS {
            return Err(ConfigError::invalid(
                "k",
                format!("must be ≤ {MAX_HELD_HOPS}"),
            ));
        }
        if !(tol_st.is_finite() && tol_st >= 0.0) {
            return Err(ConfigError::invalid("tol_st", "must be finite and ≥ 0"));
        }
        if !(0.0..=1.0).contains(&min_share) {
            return Err(ConfigError::invalid("min_share", "must be in [0, 1]"));
        }
        Ok(HeldRange {
            all: PriorRange::with_prior(prior, fade_hops, p)?,
            held: PriorRange::with_prior(prior, fade_hops, p)?,
            ring: [(f32::NAN, 0.0, false, true); 2 * MAX_SHADOW_HOPS + 1],
            k,
            w: 0,
            tol_st,
            min_share,
            min_hops,
            n_in: 0,
            n_voiced: 0,
            n_held: 0,
        })
    }

    /// Also leaves out of the kept range every hop that is an octave shadow ([`shadow_mask`]
    /// with window `w`; module docs, "Range without octave shadows"); with `k = 0` the kept
    /// hops are the voiced ones that are not shadows. A hop is judged once its `max(k, w)`-th
    /// successor has arrived, so the first `max(k, w)` hops of a stream never count. Errors
    /// unless `w ≤` [`MAX_SHADOW_HOPS`].
    pub fn with_shadow(mut self, w: usize) -> Result<Self, ConfigError> {
        if w > MAX_SHADOW_HOPS {
            return Err(ConfigError::invalid(
                "w",
                format!("must be ≤ {MAX_SHADOW_HOPS}"),
            ));
        }
        self.w = w;
        Ok(self)
    }

    /// Feeds one hop's pitch; returns the range so far (module docs), `None` until a voiced
    /// value has arrived.
    pub fn update(&mut self, f0_hz: f32) -> Option<(f32, f32)> {
        self.update_trusted(f0_hz, false)
    }

    /// As [`HeldRange::update`], where a voiced hop with `trusted` (its pitch agreed by a
    /// second tracker) counts as held (module docs, "Range from held or agreed hops"; the
    /// streaming side of [`range_quantiles_kept_or`]). With `k = 0` and `w = 0` every voiced
    /// hop counts anyway.
    pub fn update_trusted(&mut self, f0_hz: f32, trusted: bool) -> Option<(f32, f32)> {
        self.update_sure(f0_hz, trusted, true)
    }

    /// As [`HeldRange::update_trusted`], where a hop that is not `sure` (its tracker is not
    /// confident of its pitch) never counts as held or agreed, though it still lets its
    /// neighbours be held (the streaming side of [`range_quantiles_kept_or_sure`]; module
    /// docs, "Narrowed to the sure hops"). [`HeldRange::holds`] says whether the range
    /// returned is the held one.
    pub fn update_sure(&mut self, f0_hz: f32, trusted: bool, sure: bool) -> Option<(f32, f32)> {
        let all = self.all.update(f0_hz);
        if self.k == 0 && self.w == 0 {
            return all;
        }
        let st = semitones(f0_hz);
        self.n_voiced += u64::from(st.is_some());
        // The held range's padding fades with every voiced hop, as the plain range's does.
        self.held.n += u64::from(st.is_some());
        let m = self.k.max(self.w);
        let len = 2 * m + 1;
        self.ring[self.n_in % len] = (st.unwrap_or(f32::NAN), f0_hz, trusted, sure);
        self.n_in += 1;
        if self.n_in >= len {
            // The centre of the last 2m + 1 hops.
            let ci = self.n_in - 1 - m;
            let (c, f, trusted, sure) = self.ring[ci % len];
            let at = |j: usize| self.ring[j % len].0;
            if !c.is_nan()
                && sure
                && (trusted
                    || (ci - self.k..=ci + self.k).all(|j| (at(j) - c).abs() <= self.tol_st))
                && !(ci - self.w..=ci + self.w).any(|j| (at(j) - (c + 12.0)).abs() <= SHADOW_TOL_ST)
            {
                self.held.range.update(f);
                self.n_held += 1;
            }
        }
        if self.holds() {
            self.held.get()
        } else {
            all
        }
    }

    /// Whether the last range returned was the held hops' (enough of them: at least
    /// `min_hops` and `min_share` of the voiced ones) rather than every voiced hop's. False
    /// with `k = 0` and `w = 0`, where every voiced hop counts anyway.
    pub fn holds(&self) -> bool {
        (self.k > 0 || self.w > 0)
            && self.n_held >= self.min_hops.max(1)
            && self.n_held as f32 >= self.min_share * self.n_voiced as f32
    }

    /// Back to empty.
    pub fn reset(&mut self) {
        self.all.reset();
        self.held.reset();
        self.ring = [(f32::NAN, 0.0, false, true); 2 * MAX_SHADOW_HOPS + 1];
        self.n_in = 0;
        self.n_voiced = 0;
        self.n_held = 0;
    }
}

/// Running min and max of the voiced pitches seen so far. Causal, allocation-free.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunningRange {
    range: Option<(f32, f32)>,
}

impl RunningRange {
    /// An empty range.
    pub fn new() -> Self {
        RunningRange { range: None }
    }

    /// Feeds one hop's pitch (unvoiced values are ignored); returns the range so far,
    /// `None` until a voiced value has arrived.
    #[inline]
    pub fn update(&mut self, f0_hz: f32) -> Option<(f32, f32)> {
        if f0_hz.is_finite() && f0_hz > 0.0 {
            self.range = Some(match self.range {
                None => (f0_hz, f0_hz),
                Some((lo, hi)) => (lo.min(f0_hz), hi.max(f0_hz)),
            });
        }
        self.range
    }

    /// The range so far.
    pub fn get(&self) -> Option<(f32, f32)> {
        self.range
    }

    /// Back to empty.
    pub fn reset(&mut self) {
        self.range = None;
    }
}

/// Lowest pitch [`QuantileRange`] resolves; lower values share its first cell.
const QUANTILE_F0_HZ: f64 = 16.0;
/// Cells per semitone of [`QuantileRange`].
const QUANTILE_CELLS_PER_ST: f64 = 8.0;
/// Cells of [`QuantileRange`]: ten octaves above [`QUANTILE_F0_HZ`] (16 Hz–16 kHz).
const QUANTILE_CELLS: usize = 960;

/// Running quantile range of every voiced pitch seen so far (module docs, "Running
/// quantiles"). Causal; allocates its histogram once, at construction.
#[derive(Debug, Clone, PartialEq)]
pub struct QuantileRange {
    p: f32,
    count: Vec<u32>,
    min: Vec<f32>,
    max: Vec<f32>,
    n: u64,
}

impl QuantileRange {
    /// Quantile `p` cut from each end (clamped to `[0, 0.5]`; NaN counts as 0).
    pub fn new(p: f32) -> Self {
        let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 0.5) };
        QuantileRange {
            p,
            count: vec![0; QUANTILE_CELLS],
            min: vec![f32::INFINITY; QUANTILE_CELLS],
            max: vec![0.0; QUANTILE_CELLS],
            n: 0,
        }
    }

    fn cell(f0_hz: f32) -> usize {
        let c = (f64::from(f0_hz) / QUANTILE_F0_HZ).log2() * 12.0 * QUANTILE_CELLS_PER_ST;
        if c.is_nan() || c < 0.0 {
            0
        } else {
            (c as usize).min(QUANTILE_CELLS - 1)
        }
    }

    /// Feeds one hop's pitch (unvoiced values are ignored); returns the range so far,
    /// `None` until a voiced value has arrived.
    pub fn update(&mut self, f0_hz: f32) -> Option<(f32, f32)> {
        if f0_hz.is_finite() && f0_hz > 0.0 {
            let c = Self::cell(f0_hz);
            self.count[c] += 1;
            self.min[c] = self.min[c].min(f0_hz);
            self.max[c] = self.max[c].max(f0_hz);
            self.n += 1;
        }
        self.get()
    }

    /// The range so far.
    pub fn get(&self) -> Option<(f32, f32)> {
        if self.n == 0 {
            return None;
        }
        // The k-th smallest (0-based) and the k-th largest, as `range_quantiles` picks them
        // (in f32, as it does, so that a product on .5 rounds the same way).
        let k = ((self.n - 1) as f32 * self.p).round() as u64;
        let mut seen = 0u64;
        let mut lo = f32::NAN;
        for (c, &m) in self.count.iter().zip(&self.min) {
            seen += u64::from(*c);
            if seen > k {
                lo = m;
                break;
            }
        }
        seen = 0;
        let mut hi = f32::NAN;
        for (c, &m) in self.count.iter().zip(&self.max).rev() {
            seen += u64::from(*c);
            if seen > k {
                hi = m;
                break;
            }
        }
        Some((lo, hi))
    }

    /// Back to empty.
    pub fn reset(&mut self) {
        self.count.fill(0);
        self.min.fill(f32::INFINITY);
        self.max.fill(0.0);
        self.n = 0;
    }
}

/// What a streaming range leans on while the line has not shown its own yet (module docs,
/// "Streaming range with a prior" and "Register prior").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RangePrior {
    /// Pad the running range symmetrically up to this many semitones.
    Span(f32),
    /// Widen each end of the running range towards the register `(lo_hz, hi_hz)`.
    Register(f32, f32),
}

/// Running range padded to a prior that fades (module docs, "Streaming range with a
/// prior", "Register prior"). Causal, allocation-free after construction.
#[derive(Debug, Clone, PartialEq)]
pub struct PriorRange {
    /// The unpadded range: quantile 0 (exact min and max) for [`PriorRange::new`].
    range: QuantileRange,
    prior: Pad,
    fade: f64,
    n: u64,
}

/// [`RangePrior`] in the units the padding uses.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Pad {
    Span(f64),
    Register(f64, f64),
}

impl PriorRange {
    /// A range padded up to `span_st` semitones, the padding weighted by
    /// `fade_hops / (fade_hops + n)` after `n` voiced hops (`fade_hops = ∞` never fades).
    /// Errors unless `span_st ≥ 0` and `fade_hops > 0` (both not NaN).
    pub fn new(span_st: f32, fade_hops: f32) -> Result<Self, ConfigError> {
        if !(span_st >= 0.0 && span_st.is_finite()) {
            return Err(ConfigError::invalid("span_st", "must be finite and >= 0"));
        }
        if fade_hops.is_nan() || fade_hops <= 0.0 {
            return Err(ConfigError::invalid("fade_hops", "must be > 0"));
        }
        Ok(PriorRange {
            range: QuantileRange::new(0.0),
            prior: Pad::Span(f64::from(span_st)),
            fade: f64::from(fade_hops),
            n: 0,
        })
    }

    /// The running quantile range ([`QuantileRange`], quantile `p` from each end) padded
    /// towards `prior` with the weight `fade_hops / (fade_hops + n)`. Errors as
    /// [`PriorRange::with_quantile`] does, and for a register unless
    /// `0 < lo_hz < hi_hz < ∞`.
    pub fn with_prior(prior: RangePrior, fade_hops: f32, p: f32) -> Result<Self, ConfigError> {
        match prior {
            RangePrior::Span(span_st) => Self::with_quantile(span_st, fade_hops, p),
            RangePrior::Register(lo, hi) => {
                if !(lo > 0.0 && lo < hi && hi.is_finite()) {
                    return Err(ConfigError::invalid(
                        "register",
                        "must satisfy 0 < lo < hi < inf (Hz)",
                    ));
                }
                let mut r = Self::with_quantile(0.0, fade_hops, p)?;
                r.prior = Pad::Register(f64::from(lo), f64::from(hi));
                Ok(r)
            }
        }
    }

    /// As [`PriorRange::new`], but padding the running quantile range ([`QuantileRange`],
    /// quantile `p` from each end) instead of the running min and max.
    pub fn with_quantile(span_st: f32, fade_hops: f32, p: f32) -> Result<Self, ConfigError> {
        if p.is_nan() || !(0.0..=0.5).contains(&p) {
            return Err(ConfigError::invalid("p", "must be in [0, 0.5]"));
        }
        let mut r = Self::new(span_st, fade_hops)?;
        r.range = QuantileRange::new(p);
        Ok(r)
    }

    /// Feeds one hop's pitch (unvoiced values are ignored); returns the padded range so far,
    /// `None` until a voiced value has arrived.
    #[inline]
    pub fn update(&mut self, f0_hz: f32) -> Option<(f32, f32)> {
        if f0_hz.is_finite() && f0_hz > 0.0 {
            self.n += 1;
        }
        let (lo, hi) = self.range.update(f0_hz)?;
        Some(self.padded(lo, hi))
    }

    /// The padded range so far.
    pub fn get(&self) -> Option<(f32, f32)> {
        self.range.get().map(|(lo, hi)| self.padded(lo, hi))
    }

    fn padded(&self, lo: f32, hi: f32) -> (f32, f32) {
        let (lo, hi) = (f64::from(lo), f64::from(hi));
        let w = if self.fade.is_finite() {
            self.fade / (self.fade + self.n as f64)
        } else {
            1.0
        };
        let span_st = match self.prior {
            Pad::Span(s) => s,
            Pad::Register(rlo, rhi) => {
                // `w` of the way to the register's edge, in semitones (geometric in Hz); an
                // end already beyond the edge stays where it is.
                let lo = if lo > rlo {
                    lo * (rlo / lo).powf(w)
                } else {
                    lo
                };
                let hi = if hi < rhi {
                    hi * (rhi / hi).powf(w)
                } else {
                    hi
                };
                return (lo as f32, hi as f32);
            }
        };
        let span = 12.0 * (hi / lo).log2();
        let pad = (span_st - span).max(0.0) * w / 2.0;
        if pad.is_nan() || pad <= 0.0 {
            return (lo as f32, hi as f32);
        }
        let r = (pad / 12.0).exp2();
        ((lo / r) as f32, (hi * r) as f32)
    }

    /// Back to empty.
    pub fn reset(&mut self) {
        self.range.reset();
        self.n = 0;
    }
}
